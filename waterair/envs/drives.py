"""The ends' pointing actuators in the step (``env.actuator``): from the tilts a controller commands to the tilts
the ends point at (docs/model.md §11).

A tilt vector's components (v_x, v_y) are the sines of each axis's angle from the vertical; an actuator is
commanded θ = asin(v) − θ_mount per axis and points at sin(θ_mount + its angle) after the step
(:func:`waterair.physics.actuator.respond_terminal`: the closed-form response, sub-stepped only where a limit
binds). The mount is the vertical but for the fixed mirror (``fsm``), whose mount looks along the link's calm-sea
path. Without actuators (``ideal``) the command is the pointing. Where the ends move (``env.motion``), each end
points in its own body: :func:`point` takes the command there through the end's inertial reading, and the
actuators' result into the world through its true attitude (:mod:`waterair.envs.platforms`).
"""

from __future__ import annotations

import torch

from waterair.envs import platforms
from waterair.envs.constants import StepConstants
from waterair.envs.state import Placement, StepState
from waterair.physics.actuator import DRIVE_WIDTH, Actuator, respond_terminal, terminal_angle
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


def aimed(actuator: Actuator, known: tuple, attitude: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Where a link's ends start, pre-pointed at each other along the calm-sea path as each end knows it (``known``:
    T, R and the calm-sea point ``[n, 3]``): the tilts ``[n, 4]`` (:func:`flat_tilts`) and the actuators' drive
    state ``[n, 4, DRIVE_WIDTH]`` at rest pointing there in each end's body, through its read ``attitude``
    ``[n, 8]`` where the ends move: the gimbal turned from its vertical mount, a fixed mirror from its mount."""
    tx, rx, point = known
    tilts = flat_tilts(point, tx, rx)
    body = tilts
    if attitude is not None:
        _, tx_read, _, rx_read = platforms.body_rotations(attitude)
        body = platforms.rotate_tilts(tilts, tx_read, rx_read, inverse=True)
    angle = torch.asin(body) - torch.asin(mount_tilts(actuator, point, tx, rx))
    drive = torch.zeros(*tilts.shape, DRIVE_WIDTH, dtype=tilts.dtype, device=tilts.device)
    if actuator.fixed_mount:
        drive[..., 2] = angle.clamp(-actuator.mirror_range, actuator.mirror_range)
    else:
        drive[..., 0] = angle.clamp(-actuator.gimbal_range, actuator.gimbal_range)
    return tilts, drive


def drive_to(c: StepConstants, state: StepState, command: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The tilts ``[B, 4]`` the ends point at after a step commanded to the tilts ``command`` ``[B, 4]``, and the
    actuators' new drive state ``[B, 4, DRIVE_WIDTH]`` (``c.actuator`` is set)."""
    actuator = c.actuator
    assert actuator is not None  # the kernel calls this only where the ends have actuators
    tx, rx, point = platforms.known_ends(c, state)
    mount = torch.asin(mount_tilts(actuator, point, tx, rx))
    target = torch.asin(command.clamp(-1.0, 1.0)) - mount
    moved = respond_terminal(actuator, state.drive, target, c.dt)
    return torch.sin(mount + terminal_angle(moved)), moved


def point(c: StepConstants, state: StepState, command: torch.Tensor, actuated, time, normals):
    """Where the ends point after a step commanded to ``command`` ``[B, 4]``, and what moved them: the tilts as the
    ends know them ``[B, 4]``, the actuators' new drive state, where the ends are at ``time`` ``[B]`` (their motion
    stepped by the standard normals ``normals``), and their tilts in the world ``[B, 4]`` (the last two None where
    they stand still). Each end points in its body, through its inertial reading (docs/model.md §12), then its
    actuators (§11); the rows of ``actuated`` ``[B, 1]`` that are false (the kinematic references; None: none) point
    as commanded, in the world."""
    placed: Placement | None = None
    body, drive = command, state.drive
    if c.motion is not None:
        placed = platforms.place(c, state, time, normals)
        tx_true, tx_read, rx_true, rx_read = platforms.body_rotations(placed.attitude)
        body = platforms.rotate_tilts(command, tx_read, rx_read, inverse=True)
    pointed = body
    if c.actuator is not None:
        pointed, drive = drive_to(c, state, body)
        pointed = torch.cat((limit_tilt(pointed[:, :2], c.max_tilt), limit_tilt(pointed[:, 2:], c.max_tilt)), -1)
    world = None
    if placed is not None:
        world = platforms.rotate_tilts(pointed, tx_true, rx_true)
        # as the end knows it: back through its reading (without actuators, the command, exactly)
        pointed = command if c.actuator is None else platforms.rotate_tilts(pointed, tx_read, rx_read)
        world = world if actuated is None else torch.where(actuated, world, command)
    if actuated is not None and (c.actuator is not None or placed is not None):
        pointed = torch.where(actuated, pointed, command)
    return pointed, drive, placed, world


def limit_tilt(tilt: torch.Tensor, max_tilt: float) -> torch.Tensor:
    """Scale tilt vectors ``[n, 2]`` down to |v| ≤ sin(max_tilt)."""
    norm = torch.linalg.vector_norm(tilt, dim=-1, keepdim=True)
    return tilt * (max_tilt / norm.clamp(min=max_tilt))
