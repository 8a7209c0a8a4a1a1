"""TensorDict-native TorchRL environment of B independent water-air links (docs/environment.md).

``WaterAirEnv(num_envs=1024, sea={"wind": 12.0}, device="cpu")`` or ``WaterAirEnv(EnvConfig(...))``.
"""

from __future__ import annotations

import functools
from dataclasses import replace

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import EnvBase

from waterair.core.devices import resolve_device
from waterair.envs import draws, drives, kernel, platforms
from waterair.envs.config import EnvConfig
from waterair.envs.constants import StepConstants
from waterair.envs.frames import FrameStack
from waterair.envs.rewards import Reward
from waterair.envs.sensors import Sensor, SensorSettings
from waterair.envs.specs import make_specs
from waterair.envs.state import Measurement, StepState
from waterair.envs.stepper import Stepper
from waterair.physics.motion import attitudes
from waterair.physics.paths import flat_sea_point, solve_path
from waterair.physics.surface import WaveSurface

SENSOR_SEED_MASK = 0x5E5E5E5E
"""The sensor-noise generator is seeded with ``seed XOR`` this, independent of the seas'."""
CHANNEL_SEED_MASK = 0x3C3C3C3C
"""The generator of a channel that draws (the Monte Carlo tracer, ``env/channel=montecarlo``) is seeded
with ``seed XOR`` this."""


class WaterAirEnv(EnvBase):
    """B independent water-to-air optical links, each with its own sea (docs/environment.md).

    **Action** ``[B, 4]`` in [-1, 1]: (tx_vx, tx_vy, rx_vx, rx_vy). In ``absolute`` mode the tilt
    vectors are action · sin(max_tilt); in ``delta`` mode action · sin(max_slew · dt) is added to
    the current tilt (a slew-rate-limited gimbal); in ``residual`` mode action · sin(residual_deg)
    is added to the tilts of a base controller (``residual_base``: flat-sea Snell, or the quadrant
    back-projection of the delivered packet), so the agent corrects it and never starts blind; the
    first ``latency_steps + 1`` actions after a reset, which only the reading of the parked gimbals
    informs, are not applied (the base points alone, by flat-sea Snell: docs/environment.md).
    Tilts are then limited to |v| ≤ sin(max_tilt); the transmitter points (v, +sqrt(1 − |v|²))
    and the receiver (v, −sqrt(1 − |v|²)). Values
    outside [-1, 1] are clipped; NaN actions raise ``ValueError``.

    **Observation** ``[B, 8]``: transmitter pointing (3), receiver pointing (3), the intensity
    feature (log10(I + 1e-6) + 6) / 6 (1), relative time t / T_episode (1). Opt-in extras, in this
    order: ``spot`` (2: where the arrival spot sits on a quadrant detector, the arriving ray's
    direction in the receiver frame divided by tan ω_A), ``spot_valid`` (1: 0 with no reading, the
    spot then 0), ``beacon`` (2: where the drone's beacon arrives on the transmitter's detector, its
    direction in the transmitter frame over tan of the detector's half field of view), ``beacon_valid``
    (1), ``history`` (``history_length`` previous intensity features, newest first),
    ``action_history`` (the last ``history_length`` actions, newest first) and ``geometry`` (2: the
    drone's horizontal position relative to the transmitter over tx_depth + rx_height).
    ``EnvConfig.observation_layout`` names where each part sits. With ``frames`` = k > 1 the
    observation is the last k such frames side by side, newest first (a reset repeats its first).

    **Sensing**: pointing, intensity, spot and history come in a measurement packet that reaches the
    observation ``latency_steps`` late (the drone's readings, over the return link), with the sensor's noise,
    saturation and gating (:mod:`waterair.envs.sensors`); the beacon, read at the transmitter where the
    controller runs, at once, in the frame of the present pointing; time, action history and geometry are
    current. The default (ideal) sensor reports the true values at once.

    **Reward** ``[B, 1]``: :class:`waterair.envs.rewards.Reward` of the intensity I = G / G_0, where G_0
    is the aligned calm-sea gain of the same geometry.

    **Start**: new sea phases and jittered frequencies per link (and wind, offset, drone azimuth and
    wind direction drawn from their ranges when domain randomisation is configured, or taken from
    the ``*_values`` lists, link i using entry i mod their length), transmitter straight up, receiver
    straight down, t = 0. A ``_reset`` mask resets only the masked links. With ``replicas`` = k the
    batch is k copies of B / k links: link i and link i + B / k get the same sea (and wind and
    offset), common random numbers for comparing policies on identical seas in one batch; a
    ``_reset`` mask resets them together (else a ValueError), and the channel computes what does
    not depend on the pointing once per link.

    **Termination**: none; ``truncated`` (and ``done``) after ``max_steps`` steps (500 → 25 s).

    Besides the observation each step writes ``gain`` G (1/m²), ``gain_upper_bound`` G_UB,
    ``intensity`` I, ``path_valid``, ``alpha_d``/``alpha_a`` (rad), ``departure``/``arrival`` unit
    path directions, ``tx_position``/``rx_position`` (m) and ``tilt``, the present tilt vectors
    (tx_vx, tx_vy, rx_vx, rx_vy) the gimbals were commanded to, for evaluation and the baselines,
    and ``base_tilt``, the residual base controller's tilts for the next action.
    The simulator state lives on the device chosen at construction. Building or stepping one changes nothing
    outside it (what our entry points switch on for speed: :func:`~waterair.core.process.set_up_process`).
    """

    batch_locked = True

    def __init__(self, config: EnvConfig | None = None, *, reward: Reward | None = None, **overrides):
        config = (config or EnvConfig()).replace(**overrides) if overrides else (config or EnvConfig())
        super().__init__(device=resolve_device(config.device), batch_size=torch.Size([config.num_envs]))
        self.config = config
        self.reward_fn = reward or Reward()
        self.sea, self.link, self.channel = config.sea, config.geometry, config.channel_model()
        self.optics = self.channel.optics
        self.float_dtype = getattr(torch, config.dtype)
        self.observation_size = config.observation_size
        specs = make_specs(self.observation_size, self.float_dtype)
        self.observation_spec_unbatched, self.action_spec_unbatched = specs.observation, specs.action
        self.reward_spec_unbatched, self.done_spec_unbatched = specs.reward, specs.done
        self._generator = torch.Generator()
        self._sensor_generator = torch.Generator()
        self._channel_generator = torch.Generator()
        self.link_episodes = torch.zeros(config.num_envs // config.replicas, dtype=torch.int64)
        """Each distinct link's resets so far (CPU int64): a part of its keyed draws' key (``env.draws=keyed``)."""
        self._set_seed(config.seed)
        self.sensor = Sensor(
            [SensorSettings(**replica.sensing) for replica in config.replica_configs()],
            half_fov=self.optics.half_fov,
            generator=self._sensor_generator,
            beacon_half_fov=config.beacon.half_fov,
        )
        self._noise_keys = draws.noise_keys(config)
        self.constants = StepConstants.of(config, self.sensor, self.reward_fn, self.channel)
        self.stepper = Stepper(
            self.constants,
            config.solver,
            config.compile_kernel,
            self._channel_generator,
            device=self.device,
            dtype=self.float_dtype,
        )
        columns = kernel.observation_columns(config)
        self._columns = None if columns is None else torch.tensor(columns, device=self.device)
        self._allocate_state()
        self._stack = None
        if config.frames > 1:
            self._stack = FrameStack(config.num_envs, config.frames, config.frame_size, self.float_dtype, self.device)
        self._reset_rows(torch.arange(config.num_envs, device=self.device))

    # --- TorchRL interface ------------------------------------------------------------------

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None if tensordict is None else tensordict.get("_reset", None)
        if mask is None:
            rows = torch.arange(self.batch_size[0], device=self.device)
        else:
            chosen = mask.reshape(self.batch_size[0], -1).any(-1)
            copies = chosen.reshape(self.config.replicas, -1)
            if not bool((copies == copies[:1]).all()):
                raise ValueError(
                    f"a _reset mask must reset the replicas of a link together (env.replicas = "
                    f"{self.config.replicas}: link i with link i + {copies.shape[1]}, ...), so that they keep "
                    "sharing their seas"
                )
            rows = chosen.nonzero().squeeze(-1)
        if rows.numel():
            self._reset_rows(rows)
        full = self._full_state()
        constants = self.constants.for_links(full.divergence)
        delivered = kernel.deliver(full.packets, constants.sensor.latency_steps)
        self.state = replace(self.state, base_tilt=kernel.base_tilts(constants, full, delivered=delivered))
        out = self._output(kernel.observe(constants, full, delivered), reset=rows)
        done = torch.zeros(*self.batch_size, 1, dtype=torch.bool, device=self.device)
        out.update({"done": done, "terminated": done.clone(), "truncated": done.clone()})
        return out

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action")
        if torch.isnan(action).any():
            bad = torch.isnan(action).any(-1).nonzero().squeeze(-1).tolist()
            raise ValueError(
                f"action contains NaN (links {bad[:8]}{'…' if len(bad) > 8 else ''}); actions must be finite"
            )
        action = action.to(self.float_dtype).clamp(-1.0, 1.0)
        noise = self.sensor.draw(self._noise_keys, self.float_dtype, self.device)
        if self.config.motion.moves:  # the step's draws of the ends' motion, beside the readings'
            noise = draws.motion_normals(self._noise_keys, noise, self._sensor_generator, self.float_dtype, self.device)
        result = self.stepper(self.surface, self._full_state(), action, noise)
        self.state, outputs = result.state, result.outputs
        self.measurement = outputs.measurement
        out = self._output(outputs.observation)
        truncated = outputs.truncated
        out.update(
            {
                "reward": outputs.reward,
                "done": truncated,
                "terminated": torch.zeros_like(truncated),
                "truncated": truncated.clone(),
            }
        )
        return out

    def _set_seed(self, seed: int | None) -> None:
        # Random numbers are drawn on CPU generators, so a seed gives the same seas on any device.
        # Sensor noise has its own generator: noisy and ideal sensors see the same seas.
        self.link_episodes.zero_()
        if seed is None:
            self._generator.seed()
            self._sensor_generator.seed()
            self._channel_generator.seed()
        else:
            self._generator.manual_seed(int(seed))
            self._sensor_generator.manual_seed(int(seed) ^ SENSOR_SEED_MASK)
            self._channel_generator.manual_seed(int(seed) ^ CHANNEL_SEED_MASK)

    @property
    def rng(self) -> torch.Generator:
        """The environment's own CPU generator (seas, domain randomisation); save and restore its state."""
        return self._generator

    @property
    def sensor_rng(self) -> torch.Generator:
        """The CPU generator of the sensor noise; save and restore its state with :attr:`rng`'s."""
        return self._sensor_generator

    # --- helpers for policies ---------------------------------------------------------------

    def observation_part(self, observation: torch.Tensor, name: str) -> torch.Tensor:
        """The part ``name`` of observations ``[..., size]`` (see ``EnvConfig.observation_layout``)."""
        return observation[..., self.config.observation_layout[name]]

    def action_for_pointing(
        self,
        tx_dir: torch.Tensor,
        rx_dir: torch.Tensor,
        current: torch.Tensor | None = None,
        base: torch.Tensor | None = None,
        divergence: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """The action ``[n, 4]`` that best points the ends along ``tx_dir`` (up) and ``rx_dir`` (down).

        Absolute mode: the target tilts (clipped to the action box); delta mode: the step toward
        them allowed by the slew limit, from the ``current`` tilts ``[n, 4]`` (tx_vx, tx_vy,
        rx_vx, rx_vy; default: the whole batch's present pointing); residual mode: the deviation
        from the base controller's tilts ``base`` ``[n, 4]`` (the ``base_tilt`` key; default: the batch's),
        in units of each link's reach (with ``env.residual_beams``, from its ω_D ``divergence`` ``[n]``, the
        ``divergence`` key; default: the batch's).
        """
        target = torch.cat((tx_dir[:, :2], rx_dir[:, :2]), dim=-1).to(self.float_dtype)
        if self.config.action_mode == "absolute":
            return (target / self.config.max_tilt).clamp(-1.0, 1.0)
        if self.config.action_mode == "residual":
            base = self.state.base_tilt if base is None else base.to(self.float_dtype)
            reach: float | torch.Tensor = self.constants.actions.residual
            if self.constants.actions.beams is not None:
                divergence = self.state.divergence if divergence is None else divergence
                reach = kernel.residual_reach(self.constants.actions, divergence.to(self.float_dtype))
                reach = reach.repeat_interleave(2, -1)
            return ((target - base) / reach).clamp(-1.0, 1.0)
        if current is None:
            current = self.tilt
        return ((target - current.to(self.float_dtype)) / self.constants.slew_step).clamp(-1.0, 1.0)

    def unconverged_links(self) -> torch.Tensor:
        """Which links ``[B]`` (bool) the next step's fixed-iteration path solve would leave unconverged,
        from the present state (the solver's statistics: docs/benchmarks.md)."""
        state = self._full_state()
        return ~kernel.solve(self.constants, state, state.time + self.config.dt).converged

    # --- internals --------------------------------------------------------------------------

    def _allocate_state(self) -> None:
        batch, device, dtype = self.batch_size[0], self.device, self.float_dtype

        def zeros(*shape, kind=dtype):
            return torch.zeros(batch, *shape, dtype=kind, device=device)

        self.surface = WaveSurface.sample(self.sea, batch, generator=self._generator, device=device, dtype=dtype)
        tx, rx = (v.to(device, dtype).expand(batch, 3) for v in self.link.positions(torch.float64))
        prepared = self.channel.prepare(tx, rx, self.surface.unresolved)
        config = self.config
        latency = self.sensor.longest_latency
        self.state = StepState.zeros(self.surface.harmonics, prepared, config.history_length, latency,
                                     tracking=self.constants.tracks is not None)  # fmt: skip
        self.measurement = Measurement(
            gain=zeros(),
            gain_upper_bound=zeros(),
            intensity=zeros(),
            path_valid=zeros(kind=torch.bool),
            alpha_d=zeros(),
            alpha_a=zeros(),
            departure=zeros(3),
            arrival=zeros(3),
        )

    def _full_state(self) -> StepState:
        """The step's input: :attr:`state` on the seas of :attr:`surface`."""
        return replace(self.state, sea=self.surface.harmonics)

    @property
    def tilt(self) -> torch.Tensor:
        """The present commanded tilt vectors (tx_vx, tx_vy, rx_vx, rx_vy), ``[B, 4]`` (the ``tilt`` key)."""
        return self.state.command.clone()

    @property
    def pointed(self) -> torch.Tensor:
        """The tilt vectors the ends point at, ``[B, 4]`` (the ``pointed`` key): the command, but where the
        actuators (``env.actuator``) have not reached it."""
        return torch.cat((self.state.tx_tilt, self.state.rx_tilt), dim=-1)

    def _reset_rows(self, rows: torch.Tensor) -> None:
        """New seas, geometry and a cold path solve for ``rows`` (``[n]`` indices), drawn here; the state they start
        from recorded as a step records it (:func:`kernel.start`), written into the rows whatever its entries."""
        config, dtype = self.config, self.float_dtype
        distinct, copy = draws.distinct_links(config, rows)
        source = self._draws(distinct)
        wind, direction = draws.sea_conditions(config, distinct, source)
        uniform = functools.partial(source.uniform, links=distinct.numel())
        conditions = {"device": self.device, "dtype": dtype, "wind": wind, "wind_direction_deg": direction}
        surface = WaveSurface.from_uniforms(self.sea, distinct.numel(), uniform, **conditions)
        self.surface[rows] = surface[copy.to(self.device)] if config.replicas > 1 else surface
        offset, azimuth = draws.geometry(config, distinct, source)
        offset, azimuth = offset[copy.cpu()], None if azimuth is None else azimuth[copy.cpu()]
        tx, rx = (v.to(self.device, dtype) for v in self.link.positions_for(offset, azimuth))
        divergence = draws.divergence(config, distinct, source)[copy.cpu()].to(self.device)
        constants = self.constants.for_links(divergence, self.constants.replica_of(rows, config.num_envs))
        reference = self.channel.reference_gain(tx.double(), rx.double()).to(dtype)
        prepared = constants.channel.prepare(tx, rx, self.surface.unresolved[rows])
        flat = flat_sea_point(tx, rx, self.optics.n_water, self.optics.n_air)
        seas = self.surface[rows]
        at_rest = StepState.zeros(seas.harmonics, prepared, config.history_length, self.sensor.longest_latency,
                                  tracking=self.constants.tracks is not None)  # fmt: skip
        if config.motion.moves:  # the motion's start, and the ends where it has them at t = 0
            at_rest = self._moving(at_rest, (distinct, copy, source), tx, rx)
            tx, rx, flat = at_rest.tx_position, at_rest.rx_position, at_rest.flat_point
        links = replace(
            at_rest,
            tx_position=tx,
            rx_position=rx,
            divergence=divergence,
            flat_point=flat,
            reference_gain=reference,
            prepared=prepared,
        )
        attitude = attitudes(links.motion) if config.motion.moves else None
        if config.actuator.moves:  # slewing ends start pre-pointed at each other, not from upright (docs/model.md §11)
            known = links.known.unbind(1) if config.motion.moves else (tx, rx, flat)
            tilts, drive = drives.aimed(config.actuator, known, attitude)
            links = replace(links, tx_tilt=tilts[:, :2], rx_tilt=tilts[:, 2:], command=tilts, drive=drive)
        path = solve_path(
            seas,
            tx,
            rx,
            links.time,
            config.solver,
            init=flat[:, :2],
            indices=self.optics.indices,
            compiled=config.compile_kernel,
        )
        noise = self.sensor.draw(self._noise_keys[rows.cpu()], dtype, self.device)
        world = None if attitude is None else platforms.through_attitude(links.command, attitude)
        started, measurement = kernel.start(constants, links, path, noise, self.stepper.generator, world)
        self.state.write_rows(rows, started)
        for mine, value in zip(self.measurement, measurement, strict=True):
            mine[rows] = value

    def _moving(self, links: StepState, drawn: tuple, tx: torch.Tensor, rx: torch.Tensor):
        """``links`` at rest with their home at ``tx``, ``rx``, their motion's stationary start drawn (``drawn``: the
        distinct links, where each row is among them, their draws) and the ends placed where it has them at t = 0."""
        distinct, copy, source = drawn
        motion = self.config.motion
        start = draws.motion_start(self.config, distinct, source)[copy.cpu()].to(self.device, tx.dtype)
        velocity = motion.velocity(tx.dtype).to(self.device).expand_as(tx)
        if motion.kind == "parked":  # still, at a point of the crossing drawn per link
            stretch = 2.0 * motion.crossing(self.config.episode_seconds)
            at = (draws.parking(source, distinct)[copy.cpu()].to(self.device, tx.dtype) - 0.5) * stretch
            rx = rx + at.unsqueeze(-1) * motion.velocity(tx.dtype, parked=True).to(self.device)
        home = torch.stack((tx, rx, velocity), dim=1)
        clock = (links.time, self.config.episode_seconds)
        at = platforms.locate(motion, links.sea, home, start, clock, None, self.optics.indices)
        return replace(links, home=home, motion=start, known=at.known, tx_position=at.tx_position,
                       rx_position=at.rx_position, flat_point=at.flat_point)  # fmt: skip

    def _draws(self, distinct: torch.Tensor) -> draws.StreamDraws | draws.KeyedDraws:
        """Where the reset of the ``distinct`` links draws from (``env.draws``); keyed draws count each link's
        episode."""
        if self.config.draws == "stream":
            return draws.StreamDraws(self._generator)
        episodes = self.link_episodes[distinct.cpu()]
        self.link_episodes[distinct.cpu()] += 1
        return draws.KeyedDraws(draws.link_keys(self.config, self._generator.initial_seed(), distinct, episodes))

    def _output(self, observation: torch.Tensor, reset: torch.Tensor | None = None) -> TensorDict:
        """The step's TensorDict, with the observation's parts of this layout (of all parts), stacked
        with the earlier frames when ``frames`` > 1 (``reset``: the rows that start a new stack)."""
        if self._columns is not None:
            observation = observation.index_select(-1, self._columns)
        if self._stack is not None:
            observation = self._stack.push(observation) if reset is None else self._stack.reset(reset, observation)
        state = self.state
        out = {key: value.clone() for key, value in self.measurement._asdict().items()}
        tx, rx, flat = platforms.known_ends(self.constants, state)  # what the controllers know of where they are
        out.update(
            observation=observation,
            tx_position=tx.clone(),
            rx_position=rx.clone(),
            flat_point=flat.clone(),
            divergence=state.divergence.clone(),
            tilt=self.tilt,
            pointed=self.pointed,
            base_tilt=self.state.base_tilt.clone(),
        )
        return TensorDict(out, batch_size=self.batch_size, device=self.device)
