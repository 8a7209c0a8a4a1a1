"""The learned agent: its networks and the one file format its policy is saved and loaded in."""

from waterair.agents.checkpoint import POLICY_FORMAT, CheckpointError, PolicyFile, read_policy, save_policy
from waterair.agents.networks import ACTIVATIONS, make_actor, make_critic

__all__ = [
    "ACTIVATIONS",
    "POLICY_FORMAT",
    "CheckpointError",
    "PolicyFile",
    "make_actor",
    "make_critic",
    "read_policy",
    "save_policy",
]
