"""The ends' own motion in the step (``env.motion``): where the vehicle and the drone are at a step, what their
controllers know of it, and how each end's attitude turns a pointing in its own frame into the world's
(docs/model.md §12).

A link keeps its *home* (the positions its reset drew, and the drone's transit velocity) and its motion's state:
the drone's drift and each end's attitude and inertial error, drawn stationary at the reset from the link's
keyed draws, then stepped exactly each step (:func:`waterair.physics.motion.motion_step`) from standard normals
drawn as the sensor's noise is (:mod:`waterair.envs.noise`). At a step's time the vehicle is at home
plus the water's orbital motion there (times its response), and the drone on its path (home, plus its transit
about the episode's middle) plus its drift. The controllers know the path, not the drift nor the orbit: the
``known`` ends (and their calm-sea point) are what :func:`known_ends` gives every controller, the true ones
what the light follows.

Each end points in its body frame: a command in the known world frame goes through the attitude its inertial
sensor reads (Rᵀ_imu), the actuator moves in the body, and the body's true attitude carries the result into the
world (R_true). With a perfect inertial sensor and ideal actuators the two cancel. Without motion
(``static``) none of this runs: the step is the earlier one bit for bit.
"""

from __future__ import annotations

import torch

from waterair.envs.constants import StepConstants
from waterair.envs.state import Placement, StepState
from waterair.physics.channel import pointing
from waterair.physics.motion import Motion, attitudes, motion_step, orbital_motion, rotation
from waterair.physics.optics import RefractiveIndices
from waterair.physics.paths import flat_sea_point, flat_sea_point_near
from waterair.physics.surface import Harmonics


def known_ends(c: StepConstants, state: StepState) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """T, R and the calm-sea point ``[B, 3]`` each as the controllers know them: the true ones on a still link."""
    if c.motion is None:
        return state.tx_position, state.rx_position, state.flat_point
    return state.known[:, 0], state.known[:, 1], state.known[:, 2]


def place(c: StepConstants, state: StepState, time: torch.Tensor, normals: torch.Tensor | None) -> Placement:
    """The ends of ``state``'s links at ``time`` ``[B]`` (s), a step on, their motion stepped by the standard normals
    ``normals`` ``[B, MOTION_WIDTH]``; their calm-sea points from the last ones (they move little in a step)."""
    assert c.motion is not None  # the kernel places the ends only where they move
    if normals is None:
        raise ValueError("ends that move (env.motion) need each step's draws of it: SensorNoise.motion, which "
                         "WaterAirEnv draws (waterair.envs.draws.motion_normals)")  # fmt: skip
    motion = motion_step(c.motion, state.motion, normals, c.dt, c.motion_transitions)
    near = (state.flat_point, state.known[:, 2])
    return locate(c.motion, state.sea, state.home, motion, (time, c.episode_seconds), near, c.optics.indices)


def locate(
    motion: Motion,
    sea: Harmonics,
    home: torch.Tensor,
    state: torch.Tensor,
    clock: tuple[torch.Tensor, float],
    near: tuple[torch.Tensor, torch.Tensor] | None,
    indices: RefractiveIndices,
) -> Placement:
    """:func:`place` from the parts: the links' ``home`` ``[B, 3, 3]`` (T, R, the transit velocity), their motion's
    ``state`` ``[B, MOTION_WIDTH]`` at the time, ``clock`` (the time, the episode's length), the last calm-sea points
    ``near`` (true, known; None: solved afresh, as at a reset)."""
    time, episode = clock
    tx_home, rx_home, velocity = home.unbind(1)
    known_rx = rx_home + velocity * (time - motion.crossing(episode)).unsqueeze(-1).to(home.dtype)
    tx = tx_home + orbital_motion(sea, tx_home, time, motion.vehicle_response).displacement
    rx = known_rx + state[:, :3]
    if near is None:
        flat, known_flat = flat_sea_point(tx, rx, *indices), flat_sea_point(tx_home, known_rx, *indices)
    else:  # the path's calm-sea point moves only in transit
        flat = flat_sea_point_near(tx, rx, near[0], *indices)
        known_flat = flat_sea_point_near(tx_home, known_rx, near[1], *indices) if motion.kind == "transit" else near[1]
    known = torch.stack((tx_home, known_rx, known_flat), dim=1)
    return Placement(tx, rx, flat, known, attitudes(state), state)


def through_attitude(command: torch.Tensor, attitude: torch.Tensor) -> torch.Tensor:
    """Where ends without actuators point in the world ``[B, 4]`` when commanded to ``command`` ``[B, 4]`` (tilts in
    the known world frame), through each end's read and true ``attitude`` ``[B, 8]`` (:class:`Placement`'s)."""
    tx_true, tx_read, rx_true, rx_read = body_rotations(attitude)
    return rotate_tilts(rotate_tilts(command, tx_read, rx_read, inverse=True), tx_true, rx_true)


def body_rotations(attitude: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The body-to-world rotations ``[B, 3, 3]`` of the transmitter's true and read attitudes, then the
    receiver's, from a placement's ``attitude`` ``[B, 8]`` (roll, pitch; no yaw)."""
    yaw = torch.zeros_like(attitude[:, 0])
    return tuple(rotation(attitude[:, 2 * i], attitude[:, 2 * i + 1], yaw) for i in range(4))  # type: ignore[return-value]


def rotate_tilts(tilts: torch.Tensor, tx_rotation: torch.Tensor, rx_rotation: torch.Tensor, inverse: bool = False):
    """Tilts ``[B, 4]`` (tx's, then rx's) of directions turned by each end's rotation ``[B, 3, 3]`` (its transpose
    with ``inverse``): the transmitter's pointing up, the receiver's down."""
    turned = []
    for tilt, matrix, up in ((tilts[:, :2], tx_rotation, True), (tilts[:, 2:], rx_rotation, False)):
        matrix = matrix.transpose(-1, -2) if inverse else matrix
        turned.append(torch.einsum("bij,bj->bi", matrix, pointing(tilt, up=up))[:, :2])
    return torch.cat(turned, dim=-1)
