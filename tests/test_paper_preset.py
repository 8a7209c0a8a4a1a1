"""The paper's preset is the paper's physics, bit for bit, on every machine: no recording needed.

``+experiment=paper`` builds the environment as train.py does; the test steps it (float64, eager) and computes
the same rollout through the physics layer a notebook would use: the refracted path by the masked Newton
iterations from the extrapolated last two points (three, the rest finished ``FINISH_ITERATIONS`` at a time:
the step's solver), the paper's gain eq. (1) (:func:`channel_gain`) for the commanded pointing, the intensity over the
calm-sea gain G_0, the paper's LE reward and its 8-value observation written here. Both run in one process, so
they round alike on any CPU: a change to the preset or to the paper's step (its sea's time, its path, its
gain, its sensing, its reward, its observation) fails here wherever the suite runs, where the recorded
rollouts of tests/test_channel_reference.py can only be compared exactly on the machine that made them.
The sea is the environment's: its sampling is checked to the bit against the paper's recipe in tests/test_sea.py.
"""

import torch

from tests.conftest import compose_config
from waterair.envs.stepper import FINISH_ITERATIONS
from waterair.physics.channel import LinkGeometry, Transceiver, calm_sea_gains, channel_gain, pointing
from waterair.physics.optics import RefractiveIndices
from waterair.physics.paths import FixedNewtonOptions, PathProblem, finish_path, flat_sea_point, solve_path
from waterair.physics.paths.fixed import finish_unconverged, iterate_fixed
from waterair.training.builders import make_env

LINKS, STEPS = 4, 30
PAPER = {"max_tilt": 0.7071067811865475, "dt": 0.05, "episode_seconds": 25.0, "newton_iterations": 3}
"""The paper's step: tilt vectors up to sin 45°, 50 ms, 500-step episodes, three Newton iterations a step."""


def environment_rollout(env, actions):
    td, trace = env.reset(), []
    for action in actions:
        td = env.step(td.set("action", action))["next"]
        trace.append({key: td[key] for key in ("gain", "intensity", "reward", "observation", "alpha_d", "alpha_a")})
    return trace


def physics_rollout(surface, actions):
    """The paper's step through the physics layer: default geometry (10 m deep, 10 m high, 10 % offset) and
    transceiver, absolute tilts, an ideal sensor."""
    optics, n_w, n_a = Transceiver(), 1.33, 1.0
    tx, rx = (v.expand(LINKS, 3).contiguous() for v in LinkGeometry().positions(torch.float64))
    flat = flat_sea_point(tx, rx, n_w, n_a)
    g_0 = calm_sea_gains(tx, rx, optics)
    start = solve_path(surface, tx, rx, torch.zeros(LINKS, dtype=torch.float64), "newton", init=flat[:, :2])
    point = previous = torch.where(start.valid.unsqueeze(-1), start.point, flat)
    time, trace = torch.zeros(LINKS, dtype=torch.float64), []
    for action in actions:
        time = time + PAPER["dt"]  # the clock adds a step at a time, as a step does
        guess = 2.0 * point[:, :2] - previous[:, :2]
        problem = PathProblem(surface, tx, rx, time, RefractiveIndices(n_w, n_a))
        first = FixedNewtonOptions(iterations=PAPER["newton_iterations"])
        stop = iterate_fixed(problem, guess, first, False)
        stop = finish_unconverged(problem, stop, FixedNewtonOptions(iterations=FINISH_ITERATIONS), False)
        path = finish_path(stop, tx, rx, RefractiveIndices(n_w, n_a))
        tx_dir = pointing(action[:, :2] * PAPER["max_tilt"], up=True)
        rx_dir = pointing(action[:, 2:] * PAPER["max_tilt"], up=False)
        gain = channel_gain(path, tx_dir, rx_dir, optics)
        intensity = gain.gain / g_0
        # the LE reward (paper Sec. IV-B): G_r (ln(a I + 1) + log10(b max(I, floor)) + exp(c I)) + B
        terms = torch.log1p(10.0 * intensity) + torch.log10(100.0 * intensity.clamp(min=1e-3))
        reward = 0.1 * (terms + torch.exp(0.7 * intensity)) + 0.0
        feature = (torch.log10(intensity + 1e-6) + 6.0) / 6.0
        observation = torch.cat(
            (tx_dir, rx_dir, feature.unsqueeze(-1), (time / PAPER["episode_seconds"]).unsqueeze(-1)), -1
        )
        trace.append(
            {
                "gain": gain.gain,
                "intensity": intensity,
                "reward": reward.unsqueeze(-1),
                "observation": observation,
                "alpha_d": gain.alpha_d,
                "alpha_a": gain.alpha_a,
            }
        )
        stored = torch.where(path.valid.unsqueeze(-1), path.point, flat)  # a lost path restarts from the calm point
        previous, point = torch.where(path.valid.unsqueeze(-1), point, stored), stored
    return trace


def test_the_paper_preset_steps_the_papers_physics_bit_for_bit():
    overrides = [f"env.num_envs={LINKS}", "env.sea.n_freq=16", "env.sea.n_dir=8", "env.dtype=float64"]
    cfg = compose_config("config", ["+experiment=paper", *overrides, "env.compile_kernel=false", "seed=5"])
    env = make_env(cfg)
    assert {key: getattr(env.base_env.config, key) for key in PAPER} == PAPER
    actions = 0.3 * torch.rand(STEPS, LINKS, 4, generator=torch.Generator().manual_seed(1), dtype=torch.float64) - 0.15
    got = environment_rollout(env, actions)
    want = physics_rollout(env.base_env.surface.clone(), actions)
    lit = torch.stack([step["intensity"] for step in want]) > 1e-3
    assert lit.float().mean() > 0.25, lit.float().mean()  # light reached the receivers: the comparison is not of zeros
    for step, (stepped, computed) in enumerate(zip(got, want, strict=True)):
        for key, value in computed.items():
            assert torch.equal(stepped[key], value), (step, key, (stepped[key] - value).abs().max().item())
