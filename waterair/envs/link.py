"""The link budget of an environment's channel: the ``link`` group with the env's optics (docs/model.md §9).

One place that joins the two, for the ``snr`` reward, training's link scalars and the evaluation.
"""

from __future__ import annotations

from collections.abc import Mapping

from waterair.envs.config import EnvConfig
from waterair.physics.link import LinkBudget


def link_budget(values: Mapping | None, env: EnvConfig) -> LinkBudget:
    """The validated budget of the ``link`` group ``values`` with ``env``'s optics and receiver aperture.

    ``values`` None (a run saved before the link group existed) gives the defaults: the APD by day.
    Errors are one line naming ``link.<key>``.
    """
    return LinkBudget.from_mapping(dict(values or {}), optics=env.optics)
