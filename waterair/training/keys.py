"""What each key of train.py's config means, for the generated reference (docs/reference/training.md, ``make docs``).

Each entry is a key path (``seed``, ``agent.gamma``) → (unit, the values it allows and what it does). The defaults are
not here: conf/ holds them (config.yaml and each group's options), and :mod:`waterair.cli.reference` reads them from
the configs train.py composes. The ``env`` group's keys are :data:`waterair.envs.keys.KEYS`.
"""

TRAINING_KEYS: dict[str, tuple[str, str]] = {
    "seed": ("–", "≥ 0 (seeds torch and the env)"),
    "device": ("–", "auto, cpu, cuda"),
    "total_frames": ("env steps × links", "≥ 1, a multiple of `collector.frames_per_batch`"),
    "resume": ("path", "a run directory"),
    "compile_update": (
        "–",
        "true: `torch.compile` the update step; false: eager; auto: compile when the frames to go repay it "
        '(docs/training.md, "Compiles that pay")',
    ),
    "threads": ("threads", 'auto, or an integer in [1, 4096]: torch\'s intra-op threads (docs/training.md, "Threads")'),
    "eval.realisations": ("seas", "≥ 1"),
    "eval.steps": ("steps", "[1, `env.max_steps`]"),
    "eval.seed": ("–", "≥ 0"),
    "actor.name": (
        "–",
        "mlp; gru, lstm (a recurrent module on the observations, then the MLP); per_end (a MultiAgentMLP, an agent "
        "per end on its own readings): docs/training.md",
    ),
    "actor.return_steps": (
        "steps",
        "[0, 1000] (per_end: the other end's readings reach an end this many steps late; none at ≥ `env.frames`)",
    ),
    "actor.state_size": ("units", "[1, 4096] (gru, lstm: the recurrent state's width per layer)"),
    "actor.layers": ("layers", "[1, 8] (gru, lstm: stacked recurrent layers)"),
    "critic.name": ("–", "mlp"),
    "actor.hidden": ("units", "positive ints"),
    "critic.hidden": ("units", "positive ints"),
    "actor.activation": ("–", "relu, tanh, elu"),
    "critic.activation": ("–", "relu, tanh, elu"),
    "actor.lr": ("–", "(0, 1]"),
    "actor.zero_output": ("–", "start the output layer at 0: the first actions are the residual base's"),
    "critic.lr": ("–", "(0, 1]"),
    "agent.name": ("–", "ppo, ddpg, td3, sac"),
    "agent.gamma": ("–", "[0, 1)"),
    "agent.tau": ("–", "(0, 1] (ddpg, td3, sac)"),
    "agent.policy_weights": (
        "–",
        "`average`: the policy a run saves, evaluates and exports is the actor's Polyak average at rate "
        "`agent.tau` (DDPG needs `agent.loss.delay_actor=true`); `last`: the actor's last iterate",
    ),
    "agent.lmbda": ("–", "[0, 1] (ppo only: GAE's λ)"),
    "agent.max_grad_norm": ("–", "> 0 (ppo only: the gradient-norm clip of each update)"),
    "agent.target_kl": (
        "–",
        "> 0 or null (ppo only): no further pass over a batch once a pass moved the policy this far (mean "
        "approximate KL, `loss/kl`) from the one that collected it; null: every pass",
    ),
    "agent.loss.clip_epsilon": ("–", "(0, 1] (ppo only)"),
    "agent.loss.critic_coeff": ("–", "> 0 (ppo only: the critic loss's weight)"),
    "agent.loss.entropy_bonus": ("–", "true or false (ppo only: ClipPPOLoss's entropy term)"),
    "agent.loss.loss_critic_type": ("–", "l1, l2 or smooth_l1 (ppo only)"),
    "agent.loss.normalize_advantage": ("–", "true or false (ppo only: ClipPPOLoss's own)"),
    "agent.policy_delay": ("updates", "[1, 1000] (td3 only)"),
    "agent.alpha_lr": ("–", "[0, 1] (sac only: the entropy temperature's learning rate; 0 holds it at `alpha_init`)"),
    "agent.loss.alpha_init": ("reward / nat", "(0, 1000] (sac only: the entropy temperature α's start)"),
    "agent.loss.target_entropy": (
        "nats",
        "auto (−1 per action component) or a number in [−100, 100] (sac only: the entropy α is learned toward)",
    ),
    "agent.loss.delay_qvalue": ("–", "true or false: target critics (sac only)"),
    "agent.loss.loss_function": ("–", "TorchRL's choices (l1, l2, smooth_l1)"),
    "agent.loss.delay_actor": ("–", "true or false: target networks (ddpg; sac: false, it saves the actor learnt)"),
    "agent.loss.delay_value": ("–", "true or false: target networks (ddpg only)"),
    "agent.loss.policy_noise": ("action units", "[0, 10] (td3 only: target smoothing)"),
    "agent.loss.noise_clip": ("action units", "[0, 10] (td3 only: target smoothing)"),
    "buffer.name": ("–", "memory, memmap (on-disk, for 1e6+)"),
    "buffer.capacity": ("transitions", "≥ batch_size (ddpg, td3, sac; PPO keeps the last batch)"),
    "buffer.batch_size": ("transitions", "[1, 2²⁰]; PPO's minibatch, at most `collector.frames_per_batch`"),
    "buffer.scratch_dir": ("path", "memmap files (memmap only)"),
    "noise.name": ("–", "gaussian, ou (ddpg, td3)"),
    "noise.sigma_init": (
        "action units",
        "0 ≤ end ≤ init ≤ 10; PPO and SAC: their learned σ starts at `sigma_init`, and `sigma_end` must equal it",
    ),
    "noise.sigma_end": (
        "action units",
        "0 ≤ end ≤ init ≤ 10; PPO and SAC: their learned σ starts at `sigma_init`, and `sigma_end` must equal it",
    ),
    "noise.annealing_frames": ("frames", "≥ 1"),
    "noise.theta": ("1/step", "[0, 10] (ou only)"),
    "collector.frames_per_batch": ("frames", "a multiple of `env.num_envs` that divides `total_frames`"),
    "collector.init_random_frames": ("frames", "≥ 0: uniform random actions, and no updates, first"),
    "collector.updates_per_frame": ("–", "(0, 64]"),
    "logger.name": ("–", "tensorboard (event files plus `metrics.csv`)"),
    "logger.progress_bar": ("–", "tqdm bar with live reward and gain/UB"),
    "logger.dir": (
        "–",
        "the TensorBoard events' folder; null: `RUN_DIR/tensorboard`, a sweep's job "
        "`SWEEP_DIR/tensorboard/<its swept values>`",
    ),
    "checkpoint.every_frames": ("frames", "≥ 1"),
    "checkpoint.keep_buffer": ("–", "also save the replay buffer (ddpg, td3, sac)"),
    "link.power_w": ("W", "(0, 1000]: transmitted optical power P_t"),
    "link.bit_rate": ("bit/s", "(0, `cutoff_hz` / `bandwidth_per_rate`]: OOK NRZ bit rate R_b"),
    "link.bandwidth_per_rate": (
        "Hz per bit/s",
        "(0, 10]: electrical bandwidth B = this × R_b (0.5: NRZ's Nyquist bandwidth)",
    ),
    "link.fec_limit": ("–", "(0, 0.5): the largest BER the FEC corrects; above it, outage"),
    "link.filter_bandwidth_nm": ("nm", "(0, 1000]: optical band-pass filter Δλ"),
    "link.filter_transmittance": ("–", "(0, 1]: the filter's transmittance T_f (signal and background)"),
    "link.responsivity": ("A/W", "(0, 10]: ℜ at unit gain"),
    "link.gain": ("–", "[1, 10000]: avalanche gain M"),
    "link.k_a": ("–", "[0, 1]: ionisation ratio k_A of the excess noise F(M) (an APD's only)"),
    "link.dark_current": ("A", "[0, 1e-3]: primary dark current I_d (a datasheet's value at gain M, over M)"),
    "link.temperature": ("K", "(0, 10000]: noise temperature of the load"),
    "link.load_resistance": ("Ω", "(0, 1e12]: load or transimpedance R_L"),
    "link.cutoff_hz": ("Hz", "(0, 1e12]: the front end's −3 dB bandwidth; caps the rate"),
    "link.background_radiance": ("W/(m² sr nm)", "[0, 1e4]: radiance L_b in the field of view at the wavelength"),
}
