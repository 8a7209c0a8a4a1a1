"""The residual bases: the classical controllers whose tilts residual actions correct (``env.residual_base``;
docs/environment.md, "Residual actions"), each a pure function of a step's state and the readings delivered to
it, as :mod:`waterair.envs.kernel` calls them. ``kalman_tracker`` points along the tracks the state keeps
(:mod:`waterair.envs.tracks`, the filter the ``kalman_tracker`` controller runs), followed here where a step
concludes or a link resets.
"""

from __future__ import annotations

import math

import torch

from waterair.envs import platforms, tracks
from waterair.envs.constants import StepConstants
from waterair.envs.drives import flat_tilts
from waterair.envs.sensors import back_projection, beacon_pointing, read_parked
from waterair.envs.state import Readings, StepState
from waterair.physics.channel import pointing
from waterair.physics.optics import per_link, unit_vector


def flat_snell_base(c: StepConstants, state: StepState, delivered: Readings) -> torch.Tensor:
    """``flat_snell``: both ends at the calm-sea path point (as they know it)."""
    tx, rx, point = platforms.known_ends(c, state)
    return flat_tilts(point, tx, rx)


def beacon_tracker_base(c: StepConstants, state: StepState, delivered: Readings) -> torch.Tensor:
    """``beacon_tracker``: each end along its own reading, the beacon's at the transmitter, the spot's at the
    receiver (flat-sea Snell where it has none)."""
    assert c.beacon is not None  # EnvConfig.senses_beacon: a beacon base reads the beacon
    tx, rx, point = platforms.known_ends(c, state)
    flat = unit_vector(point - tx), unit_vector(point - rx)
    tx_dir, rx_dir = beacon_pointing(
        (pointing(state.tx_tilt, up=True), delivered.beacon, delivered.beacon_valid[:, 0] > 0.5),
        (delivered.rx_pointing, delivered.spot, delivered.spot_valid[:, 0] > 0.5),
        flat,
        c.beacon.half_fov,
        c.optics.half_fov,
    )
    return torch.cat((tx_dir[:, :2], rx_dir[:, :2]), dim=-1)


def aoa_tracker_base(c: StepConstants, state: StepState, delivered: Readings) -> torch.Tensor:
    """``aoa_tracker``: the quadrant detector's back-projection of the delivered packet (flat-sea Snell where it
    has no reading, or only the one read with the gimbals parked at the reset)."""
    tx, rx, point = platforms.known_ends(c, state)
    flat = unit_vector(point - tx), unit_vector(point - rx)
    seen = (delivered.spot_valid[:, 0] > 0.5) & ~read_parked(state.steps, c.sensor.latency_steps)
    tx_dir, rx_dir = back_projection(delivered.rx_pointing, delivered.spot, seen, tx, rx, flat, c.optics.half_fov)
    return torch.cat((tx_dir[:, :2], rx_dir[:, :2]), dim=-1)


def kalman_tracker_base(c: StepConstants, state: StepState, delivered: Readings) -> torch.Tensor:
    """``kalman_tracker``: each end along its Kalman track of the beacon tracker's reading, ahead over its delay
    (the state's tracks, which :func:`followed` brought up to ``delivered``)."""
    assert c.tracks is not None  # StepConstants.of: the state keeps tracks where a way corrects them
    now = state.time  # each row's lead, as the latency may be each row's
    leads = torch.stack([torch.zeros_like(now) + torch.as_tensor(lead, dtype=now.dtype, device=now.device)
                         for lead in c.tracks.leads(c.sensor.latency_steps)], -1)  # fmt: skip
    return tracks.aim(tracks.Tracks.unpacked(state.tracks), leads.unsqueeze(-1)).flatten(1)


def followed(c: StepConstants, state: StepState, delivered: Readings, start: bool = False) -> torch.Tensor:
    """The state's tracks (packed, ``[B, 2, 2, WIDTH]``) after the readings ``delivered``, or unchanged where it
    keeps none; ``start``: the links' first readings (their reset), on the state's seas."""
    if c.tracks is None:
        return state.tracks
    reading = beacon_tracker_base(c, state, delivered).unflatten(-1, (2, 2))
    if start:
        optics = c.optics
        begun = tracks.begin(reading, state.sea, optics.n_air, optics.n_water, c.tracks)
    else:
        begun = tracks.Tracks.unpacked(state.tracks)
    seen = torch.stack((delivered.beacon_valid[:, 0], delivered.spot_valid[:, 0]), -1) > 0.5
    parked = torch.stack((read_parked(state.steps, 0), read_parked(state.steps, c.sensor.latency_steps)), -1)
    assert c.beacon is not None  # a tracked base reads the beacon
    noise = (per_link(c.sensor.beacon_noise, reading[:, 0]) * math.tan(c.beacon.half_fov),
             per_link(c.sensor.spot_noise, reading[:, 1]) * math.tan(c.optics.half_fov))  # fmt: skip
    variance = torch.stack([torch.zeros_like(reading[:, 0]) + each for each in noise], 1)
    variance = variance.clamp(min=tracks.FLOOR).square()
    usable = (seen & ~parked).unsqueeze(-1).expand_as(reading)  # a link's reset reads parked gimbals
    followed = tracks.follow(begun, reading, variance, usable, parked.unsqueeze(-1).expand_as(reading), c.dt)
    return followed.packed()


RESIDUAL_BASES = {
    "flat_snell": flat_snell_base,
    "aoa_tracker": aoa_tracker_base,
    "beacon_tracker": beacon_tracker_base,
    tracks.TRACKED_BASE: kalman_tracker_base,
}
"""What residual actions correct, by ``env.residual_base``: each ``f(c, state, delivered readings)`` → the tilts
``[B, 4]``."""
