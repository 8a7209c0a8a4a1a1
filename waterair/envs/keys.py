"""What each key of the ``env`` group means, for the generated reference (docs/reference/env.md, ``make docs``).

Each entry is a key path (``num_envs``, ``sea.wind``, ``channel.rays``) → (unit, the values it allows and what it
does). The defaults are not here: the dataclasses (:class:`~waterair.envs.config.EnvConfig` and the physics objects
it holds) are their one source, and :mod:`waterair.cli.reference` reads them from there.
"""

KEYS: dict[str, tuple[str, str]] = {
    "num_envs": ("–", "[1, 2²⁴]"),
    "device": ("–", "cpu, cuda, auto"),
    "dtype": ("–", "float32, float64"),
    "seed": ("–", "null or ≥ 0"),
    "wind": ("m/s", 'null or (0, 60]: sets `sea.wind`, `wind_range` off (docs/environment.md, "The operating point")'),
    "wind_direction": ("deg", "null or [-360, 360]: sets `sea.wind_direction_deg`, `wind_direction_range` off"),
    "offset": ("–", "null or [0, 10]: sets `geometry.offset_ratio`, `offset_range` off"),
    "offset_azimuth": ("deg", "null or [-360, 360]: sets `geometry.offset_azimuth_deg`, `offset_azimuth_range` off"),
    "divergence": ("rad", "null or (0, 1.5]: sets `optics.divergence`, `divergence_range` off"),
    "sea.wind": ("m/s", "(0, 60]"),
    "sea.fetch": ("m", "(0, 1e7]"),
    "sea.gamma": ("–", "[1, 10]: JONSWAP peak enhancement (jonswap only)"),
    "sea.wind_direction_deg": ("deg", "[-360, 360]"),
    "sea.spectrum": (
        "–",
        "elfouhaily (the measured-slope sea), jonswap (the paper's sea, `+experiment=paper`), chosen with "
        "`env/spectrum=elfouhaily\\|jonswap` (the group adds that sea's own keys); docs/model.md §1",
    ),
    "sea.n_freq": ("–", "[1, 4096]: JONSWAP frequency bins over [0.6, 6] ω_p (jonswap only)"),
    "sea.n_dir": ("–", "[1, 1024]: direction bins over the downwind half-plane"),
    "sea.n_wavenumbers": ("–", "[1, 4096]: log-spaced wavenumber bins from 0.4 k_p to the cutoff (elfouhaily only)"),
    "sea.wavenumber_cutoff": (
        "rad/m",
        "(0, 1e4]: the shortest resolved wave k_c (never below 12 k_p); shorter waves are unresolved slopes "
        "(elfouhaily only)",
    ),
    "sea.amplitude": ("–", "standard, paper"),
    "geometry.tx_depth": ("m", "(0, 1e4]"),
    "geometry.rx_height": ("m", "(0, 1e4]"),
    "geometry.offset_ratio": ("–", "[0, 10]"),
    "geometry.offset_azimuth_deg": ("deg", "[-360, 360]"),
    "optics.wavelength": ("m", "(0, 1e-5]"),
    "optics.divergence": ("rad", "(0, π/2)"),
    "optics.half_fov": ("rad", "(0, π/2)"),
    "optics.concentrator_index": ("–", "[1, 3]"),
    "optics.water": ("–", "pure_sea, clear_ocean, coastal, harbor: the attenuation preset (docs/model.md §5)"),
    "optics.attenuation": ("1/m", "[0, 100], or null: the `water` preset's c"),
    "optics.n_water": ("–", "[1, 3]"),
    "optics.n_air": ("–", "from 1 to `n_water`"),
    "optics.aperture_diameter": (
        "m",
        "(0, 1]: the receiver's entrance aperture; sets the detector's collecting area and, in the full "
        "channel, the averaging of the light pattern",
    ),
    "beacon.divergence": ("rad", "(0, π/2): the drone's beacon, read at the transmitter (docs/model.md §4.9)"),
    "beacon.wavelength": ("m", "(0, 1e-5]"),
    "beacon.pointing": ("–", "receiver (along the drone's receiver boresight), nadir (straight down)"),
    "beacon.half_fov": ("rad", "(0, π/2): the transmitter's beacon detector, about its pointing"),
    "beacon.concentrator_index": ("–", "[1, 3]"),
    "actuator.kind": (
        "–",
        "ideal (the command is the pointing), gimbal, fsm (a mirror on a mount along the calm-sea path), "
        "gimbal_fsm (a gimbal carrying a mirror); both ends alike (docs/model.md §11)",
    ),
    "actuator.gimbal_range": ("rad", "(0, π/2]: the gimbal's largest angle per axis"),
    "actuator.gimbal_rate": ("rad/s", "(0, inf]"),
    "actuator.gimbal_acceleration": ("rad/s²", "(0, inf]"),
    "actuator.gimbal_natural_frequency": ("Hz", "(0, 1e5]: f_n of the gimbal's closed loop"),
    "actuator.gimbal_damping": ("–", "(0, 10]: ζ"),
    "actuator.gimbal_resolution": ("rad", "[0, 0.01]: the command's step (0: continuous)"),
    "actuator.mirror_range": ("rad", "(0, π/2]: the beam's largest deflection by the mirror per axis"),
    "actuator.mirror_natural_frequency": ("Hz", "(0, 1e5]"),
    "actuator.mirror_damping": ("–", "(0, 10]"),
    "actuator.mirror_resolution": ("rad", "[0, 0.01]"),
    "motion.kind": (
        "–",
        "static (both ends still), hover (the drone holding station, the vehicle in the sea's orbital motion), "
        "transit (hover, the drone crossing the link), parked (hover, at a point of the crossing drawn per link); "
        "docs/model.md §12",
    ),
    "motion.drift_horizontal": (
        "m",
        "[0, 100]: σ of the drone's position hold per horizontal axis (DJI's ±1.5 m GNSS hover accuracy read as 3σ; "
        "its statistic is not stated)",
    ),
    "motion.drift_vertical": ("m", "[0, 100]: σ of its height hold (DJI's ±0.5 m as 2.5σ)"),
    "motion.drift_period": ("s", "(0, 1e4]: the hold loop's natural period (assumed: no flight log found)"),
    "motion.drift_damping": ("–", "(0, 10]: its ζ"),
    "motion.drone_attitude": ("rad", "[0, 0.5]: σ of the drone's roll and pitch (1°, assumed)"),
    "motion.drone_attitude_period": ("s", "(0, 1e4]"),
    "motion.vehicle_response": ("–", "[0, 1]: of the water's orbital motion the vehicle takes (0: holds station)"),
    "motion.vehicle_attitude": ("rad", "[0, 0.5]: σ of the vehicle's roll and pitch (2°, assumed)"),
    "motion.vehicle_attitude_period": ("s", "(0, 1e4]"),
    "motion.attitude_damping": ("–", "(0, 10]: ζ of both ends' attitude"),
    "motion.imu_error": ("rad", "[0, 0.5]: σ of each end's inertial roll and pitch error (Xsens MTi-300: 0.2° RMS)"),
    "motion.imu_time": ("s", "(0, 1e4]: that error's time constant (QRSim's, a simulator's setting)"),
    "motion.transit_speed": (
        "m/s",
        "[0, 50]: `transit`: the drone's speed, crossing home at mid-episode (1.5: the tank experiments' fastest "
        "receiver)",
    ),
    "motion.transit_heading_deg": ("deg", "[-360, 360]: its heading from +x"),
    "motion.crossing_time": (
        "s",
        "null or [0, 1e6]: when the transit passes over home (null: the episode's middle); `parked`: the drone "
        "stands where the transit is at a time drawn uniformly in [0, 2 × this]",
    ),
    "channel.name": (
        "–",
        'chosen with `env/channel=full\\|single_path\\|montecarlo\\|counting` (docs/environment.md, "Channel"); '
        "each option has only its own keys below",
    ),
    "channel.nodes": (
        "–",
        "odd, [3, 31]: `full`: nodes per axis of each of its two surface lattices (docs/model.md §4.3)",
    ),
    "channel.span": (
        "–",
        "[1, 8]: `full`: the lattices' half-width in standard deviations of the blurred beam footprint",
    ),
    "channel.rays": ("–", "[1, 1e9]: `montecarlo`, `counting`: surface rays per link and step"),
    "channel.facets": ("–", "[1, 1e5]: `counting`: unresolved-slope draws per surface ray"),
    "channel.points": (
        "–",
        "[1, 1e4]: `montecarlo`: aperture points each surface hit sends its light to (the local estimate)",
    ),
    "dt": ("s", "(0, 10]"),
    "max_steps": ("steps", "[1, 1e7]"),
    "action_mode": ("–", "absolute, delta, residual"),
    "residual_deg": ("deg", "(0, 90): the largest residual correction"),
    "residual_beams": ("ω_D", "(0, 100]: caps the transmitter's correction at k·ω_D"),
    "residual_base": (
        "–",
        "flat_snell, aoa_tracker (needs `spot`, `spot_valid`), beacon_tracker and kalman_tracker (need those and "
        "`beacon`, `beacon_valid`)",
    ),
    "max_tilt_deg": ("deg", "(0, 90)"),
    "max_slew_deg_s": ("deg/s", "(0, 1e5]"),
    "actuated": ("–", "true, false (the ends point where commanded whatever `actuator`: the kinematic references)"),
    "observation_extras": (
        "–",
        "any of spot, spot_valid, beacon, beacon_valid, history, action_history, geometry, divergence (presets below)",
    ),
    "history_length": ("steps", "[1, 1000] (`history` and `action_history`)"),
    "frames": ("–", "[1, 64]: observation frames side by side, newest first"),
    "latency_steps": ("steps", "[0, 1000]: extra steps before a measurement packet reaches the controller"),
    "intensity_noise": ("–", "[0, 10]: relative standard deviation of the measured intensity"),
    "intensity_noise_floor": ("I", "[0, 10]: additive standard deviation (the detector floor)"),
    "intensity_saturation": ("I", "null or > 0: the largest measurable intensity"),
    "spot_noise_rad": ("rad", "[0, 1]: standard deviation of each spot component, as an angle"),
    "spot_threshold": ("I", "≥ 0: measured intensity below which the detector reads no spot"),
    "beacon_noise_rad": ("rad", "[0, 1]: standard deviation of each component of the beacon reading, as an angle"),
    "beacon_threshold": (
        "G_B,0",
        "≥ 0: beacon level (of its calm-sea value) below which the transmitter's detector reads nothing",
    ),
    "solver": ("–", "newton (fixed-iteration Newton in the step's graph), centroid (the paper's method, eager)"),
    "newton_iterations": (
        "–",
        "[1, 20]: masked Newton iterations of the step's graph; links left unconverged finish in a second stage",
    ),
    "wind_range": ("m/s", "null or [low, high] within (0, 60]"),
    "offset_range": ("–", "null or [low, high] within [0, 10]"),
    "offset_azimuth_range": (
        "deg",
        "null or [low, high] within [-360, 360]: the drone anywhere around the transmitter",
    ),
    "wind_direction_range": ("deg", "null or [low, high] within [-360, 360]: wind from any direction"),
    "divergence_range": ("rad", "null or [low, high] within (0, 1.5]: each link's ω_D, drawn uniformly in log ω_D"),
    "wind_values": ("m/s", "null or a non-empty list within (0, 60]; not with `wind_range`"),
    "offset_values": ("–", "null or a non-empty list within [0, 10]; not with `offset_range`"),
    "divergence_values": ("rad", "null or a non-empty list within (0, 1.5]; not with `divergence_range`"),
    "offset_azimuth_values": (
        "deg",
        "null or a non-empty list within [-360, 360]; not with the matching range. All `*_values` given "
        "together have one entry per scenario point",
    ),
    "wind_direction_values": (
        "deg",
        "null or a non-empty list within [-360, 360]; not with the matching range. All `*_values` given "
        "together have one entry per scenario point",
    ),
    "replicas": (
        "–",
        "divides `num_envs`: the batch is that many copies of `num_envs / replicas` links with identical seas",
    ),
    "replica_actions": (
        "–",
        "null, or per replica some of `action_mode`, `residual_deg`, `residual_beams`, `residual_base`: how "
        "it acts (evaluation)",
    ),
    "replica_sensing": ("–", "null, or per replica some sensing keys (evaluation)"),
    "draws": (
        "–",
        "keyed (each link's draws hashed from the seed, its realisation, its episode and the draw's role: "
        "docs/model.md §10), stream (one generator for the batch, in order: the paper's, `+experiment=paper`)",
    ),
    "link_offset": ("–", "[0, 2⁴⁰]: keyed draws: the realisation of the batch's first link"),
    "compile_kernel": (
        "–",
        'true: `torch.compile` the whole step into one graph (docs/environment.md, "The compiled step"); '
        "false: eager; auto (train.py, evaluate.py only): compile when the run's frames repay it "
        '(docs/training.md, "Compiles that pay")',
    ),
}
