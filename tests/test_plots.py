"""The evaluation's figures tell every policy apart: each baseline and classical controller has a style of its
own, each controller another for the learned policies' sensing, and no two styles share a colour or a marker."""

from types import SimpleNamespace

from waterair.envs.controllers import CONTROLLERS
from waterair.evaluation.plots import LEARNED_STYLES, SENSING_STYLES, STYLES, _style
from waterair.evaluation.rollouts import REFERENCES


def test_every_reference_and_its_second_sensing_has_a_style_of_its_own():
    assert set(REFERENCES) <= set(STYLES), set(REFERENCES) - set(STYLES)
    assert set(CONTROLLERS) <= set(SENSING_STYLES), set(CONTROLLERS) - set(SENSING_STYLES)
    styles = [*STYLES.values(), *SENSING_STYLES.values(), *LEARNED_STYLES]
    colours, markers = [style[0] for style in styles], [style[1] for style in styles]
    assert len(set(colours)) == len(colours) and len(set(markers)) == len(markers)


def test_sixteen_learned_policies_each_have_a_style_of_their_own_and_the_first_four_are_solid():
    policies = [{"kind": "learned", "label": f"seed {n}"} for n in range(16)]
    styles = [_style(SimpleNamespace(policies=policies), policy) for policy in policies]
    assert len(set(styles)) == 16
    assert [style[2] for style in styles[:4]] == ["-"] * 4 and all(style[3] == 2.2 for style in styles)
