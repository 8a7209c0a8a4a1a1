"""The prediction bound: the exact path's pointing carried over the delays a controller of the configuration faces
by the best linear predictor of the path's past (docs/environment.md, "Baselines").

``tracking`` points each end along the exact path of the step before: it knows the path perfectly and one step
late. A controller is later still: the receiver's reading reaches it ``latency_steps`` late, and the pointing it
commands trails the command by the actuators' lag (:meth:`~waterair.physics.actuator.Actuator.lag`, which a
controller that knows its actuator commands ahead by, as ``kalman_tracker`` does). Each end's delay is therefore
D = 1 + lag/Δt steps at the transmitter and D = 1 + ``latency_steps`` + lag/Δt at the receiver (:func:`delays`).
What predicting from the path's past could win back of that delay is bounded, among linear predictors, by the one
of least mean-square error, which depends only on the process's second-order statistics: the sea's spectrum and
the ends' motion processes. This reference is that oracle. Its coefficients solve the normal equations
(Wiener-Hopf, as least squares; Brockwell and Davis, *Time Series: Theory and Methods*, Springer 1991, §5.1) with
the statistics estimated on calibration links of the same configuration and seeds of their own
(:data:`CALIBRATION_SEED`), per scenario point (link i is point i mod P, :mod:`waterair.envs.draws`).

The state s_t is the four tilts (v_x, v_y) the exact path gives the transmitter and the receiver. An end of delay
k steps (an integer) knows the path up to s_{t+1−k} when it decides where to point for step t + 1; the predictor
of that horizon forecasts the move from there from the last :data:`ORDER` moves of all four tilts, their offset
from the calm-sea path's tilts and a constant:

    ŝ_{t+1} = s_{t+1−k} + W_{g,k} [s_{t+1−k} − s_{t−k}, …, s_{t+2−k−ORDER} − s_{t+1−k−ORDER}, s_{t+1−k} − s̄_{t+1−k}, 1]

so a path that stands still is predicted to stay (its moves are zero), and pointing along the last path known
(W = 0: ``tracking`` where k = 1) is among the predictors it chooses from. A delay between two integers, n + f,
points along (1 − f) times the forecast of horizon n plus f times that of n + 1 (:func:`spanned`).

A spectrum describes a smooth, Gaussian process; the exact path also jumps where the light moves to another
refraction point, which no linear predictor foresees and which, extrapolated, throws the beam off on the next
step. So the predictor is fitted and used on stretches whose last ORDER moves of each end are all within
:data:`GATE` times the median move (:func:`smooth`), and points along the last path it knows after a jump, as it
does where a link has fewer than ORDER + k valid paths since its reset (along the oldest it has seen since, where
fewer than k).
Like ``tracking`` it is kinematic: it points in the world where it commands, through neither the actuators nor
an attitude.
"""

from __future__ import annotations

import math

import torch

from waterair.envs.baselines import FlatSeaSnell, PreviousPathTracking
from waterair.envs.env import WaterAirEnv
from waterair.envs.operating_point import PER_LINK
from waterair.physics.channel import pointing
from waterair.physics.optics import unit_vector

ORDER = 4
"""The past moves the predictor reads (steps). Of 1, 2, 4 and 8, 4 held the most on still and crossing ends."""
CALIBRATION_SEED = 987_654_321
"""The calibration links' seed: none of the evaluation's scenario seeds nor a training seed."""
CALIBRATION_LINKS = 16
"""Calibration links per scenario point."""
CALIBRATION_STEPS = 2000
"""The most steps a calibration link runs."""
FRACTION = 1e-6
"""The part of a step below which a delay's lag is none (a fine mirror trails its command by ~1e-32 s at 50 ms)."""
GATE = 3.0
"""A jump: a move of an end beyond GATE times the median move (of 2, 3, 4 and none, 3 held the most)."""
RCOND = 1e-10
"""The least-squares fit's cut on singular values, relative to the largest: directions the samples leave open."""


def tilts(departure: torch.Tensor, arrival: torch.Tensor) -> torch.Tensor:
    """The tilts ``[..., 4]`` (transmitter's v_x, v_y, then the receiver's) of pointing along a path that leaves
    the transmitter along ``departure`` and reaches the receiver along ``arrival`` (unit vectors ``[..., 3]``)."""
    return torch.cat((departure[..., :2], -arrival[..., :2]), dim=-1)


def moves(history: torch.Tensor) -> torch.Tensor:
    """The moves ``[..., K − 1, 4]`` between the states ``history`` ``[..., K, 4]`` (newest first), newest first."""
    return history[..., :-1, :] - history[..., 1:, :]


def features(history: torch.Tensor, calm: torch.Tensor) -> torch.Tensor:
    """The predictor's inputs ``[..., 4 ORDER + 5]`` from the last ORDER + 1 states ``history`` ``[..., ORDER + 1,
    4]`` (newest first) and the calm-sea tilts ``calm`` ``[..., 4]`` now."""
    one = torch.ones_like(calm[..., :1])
    return torch.cat((moves(history).flatten(-2), history[..., 0, :] - calm, one), dim=-1)


def fit(
    states: torch.Tensor, calm: torch.Tensor, valid: torch.Tensor, groups: torch.Tensor, count: int, ahead: int = 1
):
    """The predictor's coefficients ``[count, 4, 4 ORDER + 5]`` over ``ahead`` steps and its gates ``[count]``
    (rad; inf where the paths never move), float64 on the CPU, per group, from calibration sequences: ``states``
    and ``calm`` ``[B, T, 4]``, ``valid`` ``[B, T]`` (whether each step's path was found) and each sequence's group
    ``groups`` ``[B]`` (long, < ``count``). A sample is a step whose ORDER + 1 + ``ahead`` paths (the history and
    the ``ahead`` after it) are all valid and :func:`smooth` (jumps are no part of the spectrum's process); each
    group's least-squares fit of the move ``ahead`` steps on, of least norm where the samples leave it open (an SVD
    with the features scaled alike, singular values below :data:`RCOND` of the largest dropped): a process that
    never moves gets W = 0, as do sequences shorter than ORDER + 1 + ``ahead``. The gate is GATE times the median
    move of one step."""
    states, calm, valid, groups = (v.detach().cpu() for v in (states.double(), calm.double(), valid, groups))
    window = ORDER + 1 + ahead
    weights = torch.zeros(count, 4, 4 * ORDER + 5, dtype=torch.float64)
    gates = torch.full((count,), math.inf, dtype=torch.float64)
    if states.shape[1] < window:
        return weights, gates  # a rollout too short to fill a history: every step points along the last path
    past = states.unfold(1, window, 1).flip(-1).transpose(-1, -2)  # [B, S, window, 4], newest first
    x = features(past[:, :, ahead:], calm[:, window - 1 - ahead : calm.shape[1] - ahead])
    y = past[:, :, 0] - past[:, :, ahead]
    step = moves(past[:, :, :2])[:, :, 0]  # the last move of one step
    usable = valid.unfold(1, window, 1).all(-1)  # [B, S]
    for group in range(count):
        chosen = usable & (groups == group).unsqueeze(-1)
        if chosen.any():
            typical = end_moves(step[chosen]).median()
            gates[group] = GATE * typical if typical > 0 else math.inf
            chosen = chosen & smooth(past, gates[group])  # the spectrum's smooth process: no jump, the next's
        inputs, targets = x[chosen], y[chosen]
        if not inputs.shape[0]:
            continue  # no sample: tracking
        scale = inputs.square().mean(0).sqrt()
        scale = torch.where(scale > 0, scale, torch.ones_like(scale))
        solution = torch.linalg.lstsq(inputs / scale, targets, rcond=RCOND, driver="gelsd").solution
        weights[group] = (solution / scale.unsqueeze(-1)).T
    return weights, gates


def end_moves(moved: torch.Tensor) -> torch.Tensor:
    """Each end's move (the norm of its tilts' change) ``[..., 2]`` from the four tilts' ``moved`` ``[..., 4]``."""
    return torch.linalg.vector_norm(moved.unflatten(-1, (2, 2)), dim=-1)


def smooth(history: torch.Tensor, gate) -> torch.Tensor:
    """Whether every move of either end in ``history`` ``[..., ORDER + 1, 4]`` is within ``gate``."""
    return (end_moves(moves(history)) <= gate).flatten(-2).all(-1)


def delays(config) -> tuple[float, float]:
    """The delays (steps) of the transmitter's and the receiver's pointing under ``config`` (the module's docstring):
    one step, the receiver's reading's ``latency_steps``, and the actuators' lag over ``env.dt`` (none where under
    :data:`FRACTION` of a step, or negative)."""
    lag = config.actuator.lag(config.dt) / config.dt
    lag = lag if lag >= FRACTION else 0.0
    return 1.0 + lag, 1.0 + config.latency_steps + lag


def spanned(delay: float) -> tuple[tuple[int, float], ...]:
    """The whole horizons a ``delay`` (steps, ≥ 1) points between and each one's weight: n and n + 1 for n + f."""
    whole = math.floor(delay)
    part = delay - whole
    return ((whole, 1.0),) if part < FRACTION else ((whole, 1.0 - part), (whole + 1, part))


def carried(forecasts: dict[int, torch.Tensor], delay: float) -> torch.Tensor:
    """The tilts forecast over ``delay`` steps from the ``forecasts`` of the whole horizons it spans
    (:func:`spanned`)."""
    (whole, weight), *after = spanned(delay)
    forecast = forecasts[whole]
    for later, share in after:
        forecast = weight * forecast + share * forecasts[later]
    return forecast


def point_count(config) -> int:
    """The scenario points ``config``'s links cycle through: the least common multiple of its ``<name>_values``'
    lengths (1 where every link draws or takes one value)."""
    lengths = [len(values) for name in PER_LINK if (values := getattr(config, f"{name}_values")) is not None]
    return math.lcm(*lengths) if lengths else 1


class PredictionBound(PreviousPathTracking):
    """``tracking`` carried over each end's delay (:func:`delays`) by the optimal linear predictor of the exact
    pointing (this module's docstring): what prediction from the path's past could win over the loop's delays.
    Fitted at construction on calibration links of its configuration (:data:`CALIBRATION_LINKS` per point, eager,
    on :data:`CALIBRATION_SEED`), one predictor per whole horizon its delays span, over the ``steps`` it will act
    for from a reset (None: a whole episode; at most :data:`CALIBRATION_STEPS`), so that a drone crossing the link
    is calibrated where it crosses; it keeps each link's last states and calm-sea tilts."""

    name = "prediction_bound"

    def __init__(self, env, config=None, steps: int | None = None):
        super().__init__(env, config)
        self.points = point_count(self.config)
        self.delays = delays(self.config)
        self.horizons = sorted({k for delay in self.delays for k, _ in spanned(delay)})
        fitted = self._calibrate(steps)
        self.coefficients = {k: weights.to(env.device) for k, (weights, _) in fitted.items()}
        self.gates = {k: gates.to(env.device) for k, (_, gates) in fitted.items()}
        self.history: torch.Tensor | None = None  # [n, ORDER + longest horizon, 4], newest first
        self.calms: torch.Tensor | None = None  # [n, longest horizon, 4], newest first
        self.known: torch.Tensor | None = None  # [n]: the consecutive valid paths in it since the reset

    @classmethod
    def for_rollout(cls, env, config, steps: int):
        """Calibrated over the rollout's ``steps``."""
        return cls(env, config=config, steps=steps)

    def _calibrate(self, steps: int | None) -> dict[int, tuple[torch.Tensor, torch.Tensor]]:
        config = self.config.replace(
            num_envs=self.points * CALIBRATION_LINKS,
            replicas=1,
            replica_actions=None,
            replica_sensing=None,
            compile_kernel=False,
            seed=CALIBRATION_SEED,
        )
        env = WaterAirEnv(config)
        env.set_seed(CALIBRATION_SEED)
        with torch.no_grad():
            steps = min(steps or config.max_steps, config.max_steps, CALIBRATION_STEPS)
            rollout = env.rollout(steps, PreviousPathTracking(env), break_when_any_done=False)
        keys = ("departure", "arrival", "path_valid", "tx_position", "rx_position", "flat_point")
        every = {key: torch.cat((rollout[key][:, :1], rollout["next", key]), dim=1) for key in keys}
        states = tilts(every["departure"], every["arrival"])
        calm = self._calm(every["tx_position"], every["rx_position"], every["flat_point"])
        groups = torch.arange(config.num_envs, device=states.device) % self.points
        valid = every["path_valid"].squeeze(-1).bool()
        return {k: fit(states, calm, valid, groups, self.points, k) for k in self.horizons}

    @staticmethod
    def _calm(tx: torch.Tensor, rx: torch.Tensor, flat: torch.Tensor) -> torch.Tensor:
        """The tilts ``[..., 4]`` of pointing both ends along the calm sea's path through ``flat``."""
        return tilts(unit_vector(flat - tx), -unit_vector(flat - rx))

    def _steps(self, rows: int) -> torch.Tensor:
        steps = self.env.state.steps
        if rows not in (steps.shape[0], steps.shape[0] // self.env.config.replicas):
            raise ValueError(f"prediction_bound acts on its environment's {steps.shape[0]} links or one replica's")
        return steps[:rows]  # replicas reset together

    def _forecast(self, k: int, groups: torch.Tensor) -> torch.Tensor:
        """The four tilts ``[n, 4]`` forecast for the next step from the path known k steps before it."""
        assert self.history is not None and self.known is not None and self.calms is not None
        past = self.history[:, k - 1 : k + ORDER]  # [n, ORDER + 1, 4]: up to s_{t+1-k}
        ahead = past[:, 0] + (self.coefficients[k][groups] @ features(past, self.calms[:, k - 1]).unsqueeze(-1))[..., 0]
        ready = (self.known > ORDER + k - 1) & smooth(past, self.gates[k][groups][:, None, None])
        oldest = (self.known.clamp(max=k) - 1).clamp(min=0)  # the last path known
        last = self.history.gather(1, oldest.view(-1, 1, 1).expand(-1, 1, 4))[:, 0]
        return torch.where(ready.unsqueeze(-1), ahead, last)

    def directions(self, tensordict):
        flat_tx, flat_rx = FlatSeaSnell.directions(self, tensordict)
        valid = tensordict.get("path_valid").reshape(-1).bool()
        state = tilts(tensordict.get("departure"), tensordict.get("arrival")).double()
        calm = self._calm(*(tensordict.get(key) for key in ("tx_position", "rx_position", "flat_point"))).double()
        rows = state.shape[0]
        started = self._steps(rows) == 0
        longest = self.horizons[-1]
        if self.history is None or self.history.shape[0] != rows:
            self.history = state.unsqueeze(1).expand(rows, ORDER + longest, 4).clone()
            self.calms = calm.unsqueeze(1).expand(rows, longest, 4).clone()
            self.known = torch.zeros(rows, dtype=torch.long, device=state.device)
        assert self.known is not None and self.calms is not None
        self.history = torch.cat((state.unsqueeze(1), self.history[:, :-1]), dim=1)
        self.calms = torch.cat((calm.unsqueeze(1), self.calms[:, :-1]), dim=1)
        self.known = torch.where(valid & ~started, self.known + 1, valid.long())
        groups = torch.arange(rows, device=state.device) % self.points
        forecasts = {k: self._forecast(k, groups) for k in self.horizons}
        ends = [
            carried(forecasts, delay)[:, 2 * e : 2 * e + 2].to(flat_tx.dtype) for e, delay in enumerate(self.delays)
        ]
        tx, rx = pointing(ends[0], up=True), pointing(ends[1], up=False)
        found = valid.unsqueeze(-1)
        return torch.where(found, tx, flat_tx), torch.where(found, rx, flat_rx)
