"""The ends' pointing actuators in the step (``env.actuator``): from the tilts a controller commands to the tilts
the ends point at (docs/model.md §11).

A tilt vector's components (v_x, v_y) are the sines of each axis's angle from the vertical; an actuator is
commanded θ = asin(v) − θ_mount per axis and points at sin(θ_mount + its angle) after the step
(:func:`waterair.physics.actuator.respond_terminal`: the closed-form response, sub-stepped only where a limit
binds). The mount is the vertical but for the fixed mirror (``fsm``), whose mount looks along the link's calm-sea
path. Without actuators (``ideal``) this module is not called: the command is the pointing.
"""

from __future__ import annotations

import torch

from waterair.envs.constants import StepConstants
from waterair.envs.state import StepState
from waterair.physics.actuator import Actuator, respond_terminal, terminal_angle
from waterair.physics.optics import unit_vector


def flat_tilts(point: torch.Tensor, tx: torch.Tensor, rx: torch.Tensor) -> torch.Tensor:
    """The tilts ``[n, 4]`` (tx_vx, tx_vy, rx_vx, rx_vy) pointing both ends at the calm-sea path point ``[n, 3]``."""
    return torch.cat((unit_vector(point - tx)[:, :2], unit_vector(point - rx)[:, :2]), dim=-1)


def mount_tilts(actuator: Actuator, flat_point, tx_position, rx_position) -> torch.Tensor:
    """The tilts ``[n, 4]`` each end's actuator is centred on: along the calm-sea path point ``[n, 3]`` for a
    fixed mount (:func:`flat_tilts`), the vertical otherwise."""
    if actuator.fixed_mount:
        return flat_tilts(flat_point, tx_position, rx_position)
    return torch.zeros(flat_point.shape[0], 4, dtype=flat_point.dtype, device=flat_point.device)


def drive(c: StepConstants, state: StepState, command: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The tilts ``[B, 4]`` the ends point at after a step commanded to the tilts ``command`` ``[B, 4]``, and the
    actuators' new drive state ``[B, 4, DRIVE_WIDTH]`` (``c.actuator`` is set)."""
    actuator = c.actuator
    assert actuator is not None  # the kernel calls this only where the ends have actuators
    mount = torch.asin(mount_tilts(actuator, state.flat_point, state.tx_position, state.rx_position))
    target = torch.asin(command.clamp(-1.0, 1.0)) - mount
    moved = respond_terminal(actuator, state.drive, target, c.dt)
    return torch.sin(mount + terminal_angle(moved)), moved
