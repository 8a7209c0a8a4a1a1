"""The packets the drone's readings travel in to the controller at the transmitter, late by the return link's
latency (docs/environment.md, "Sensing"): packed, unpacked by name and delivered (:func:`deliver`).
"""

from __future__ import annotations

import torch

from waterair.envs.sensors import PACKET_PARTS, packet_sizes
from waterair.envs.state import Packet, Readings


def pack(readings: Readings, history: torch.Tensor) -> torch.Tensor:
    """One packet ``[n, width]``: the ``readings`` and the ``history`` side by side, the parts of
    :data:`~waterair.envs.sensors.PACKET_PARTS`."""
    return torch.cat([*readings, history], dim=-1)


def unpack(packet: torch.Tensor) -> Packet:
    """The parts of one packet ``[n, width]`` by name (the inverse of :func:`pack`)."""
    history_length = packet.shape[-1] - sum(packet_sizes(0))
    parts = dict(zip(PACKET_PARTS, packet.split(packet_sizes(history_length), dim=-1), strict=True))
    history = parts.pop("history")
    return Packet(Readings(**parts), history)


def deliver(packets: torch.Tensor, latency_steps: int | torch.Tensor) -> Packet:
    """What reaches the controller, at the transmitter, of the packets in flight ``[n, slots, width]`` (newest
    first): the drone's readings, with the transmitter's pointing they were read with, over the return link,
    ``latency_steps`` late (one, the last slot; or each row's ``[n]``, where replicas sense differently); the beacon
    reading at once, the newest, for it is read at the transmitter, in the frame of its present pointing
    (docs/environment.md, "Sensing")."""
    if isinstance(latency_steps, torch.Tensor):
        slot = latency_steps.reshape(-1, 1, 1).expand(-1, 1, packets.shape[-1])
        late = unpack(packets.gather(1, slot)[:, 0])
    else:
        late = unpack(packets[:, -1])
    now = unpack(packets[:, 0]).readings
    return late._replace(readings=late.readings._replace(beacon=now.beacon, beacon_valid=now.beacon_valid))
