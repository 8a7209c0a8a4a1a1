"""Benchmarks: ``python -m waterair.bench physics|env|evaluate [--out FILE.json]``.

Every number in one JSON file comes from one run on one machine, so ratios between them are
meaningful. Timings are wall-clock medians after a warm-up.

* ``physics``: path-solve time per batch (Newton cold and warm start, centroid), surface
  evaluations per second, the sin+cos floor and the solve-to-floor ratio (:mod:`.physics`).
* ``env``: raw ``env.step`` loop and TorchRL ``rollout`` env-steps per second and peak memory per
  batch size, with the floor ratio (:mod:`.env`).
* ``controllers``: the step time the classical controllers and the realistic sensor add over the
  flat-sea Snell baseline (:mod:`.controllers`).
* ``training``: a DDPG update against bare PyTorch; train.py's frames per second (collection,
  update, whole loop; short and long runs, eager and compiled) against Stable-Baselines3 DDPG on our
  Gymnasium view, and quiet against beside a busy process (:mod:`.training`).
* ``quality``: wall time to a greedy 0.95 of the upper bound at the S1 point on the defaults, ours against
  Stable-Baselines3 DDPG and PPO, measured in one run (:mod:`.quality`).
* ``summary``: the speed targets as ratios, from the JSON files of the suites above (:mod:`.summary`).
* ``census``: refraction points per link on the measured-slope sea, their spread and the brightest
  point's share of the power (:mod:`.census`).
* ``channel``: env-steps per second of each channel model (``single_path``, ``full``) on each sea
  (paper, ocean), in one run (:mod:`.env`).
* ``montecarlo``: the full channel against the Monte Carlo reference on the measured-slope sea:
  mean power, scintillation, correlation, and the tracer's rays per second (:mod:`.montecarlo`).
* ``cutoff``: the local estimate's mean power and scintillation index as more of the sea is resolved
  (k_c = 10, 40, 100 rad/m): where the two-scale model stops (:mod:`.cutoff`).
* ``evaluate``: the default evaluation (shipped policies, every baseline, S1-S3), all policies in
  one batch against one rollout per policy (:mod:`.evaluate`).

Nothing imports this package; it may import every other one.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import torch

from waterair.bench.census import bench_census, census_table
from waterair.bench.common import machine
from waterair.bench.controllers import bench_controllers, controllers_table
from waterair.bench.cutoff import CUTOFF_HEADER, bench_cutoff
from waterair.bench.env import ENV_HEADER, bench_channels, bench_env
from waterair.bench.evaluate import bench_evaluate, evaluate_table
from waterair.bench.montecarlo import MONTECARLO_HEADER, bench_montecarlo, montecarlo_table
from waterair.bench.physics import bench_physics, physics_table
from waterair.bench.quality import CHUNK, MODES, bench_quality, known_names, quality_table
from waterair.bench.sb3 import MISSING as SB3_MISSING
from waterair.bench.sb3 import installed as sb3_installed
from waterair.bench.summary import main as summary
from waterair.bench.training import bench_training, training_table
from waterair.core.devices import resolve_device
from waterair.core.files import atomic_write_json
from waterair.core.threads import check_threads
from waterair.physics import sea_state

ROUNDS_JUDGED = ("env", "channel", "training", "quality")
"""The suites whose ratios the summary judges: three rounds each by default, judged on their median."""


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m waterair.bench", description="waterair benchmarks (JSON out)")
    sub = parser.add_subparsers(dest="suite", required=True)
    physics = sub.add_parser("physics", help="path solvers and surface evaluation")
    physics.add_argument("--sizes", type=int, nargs="+", default=[1, 64, 1024, 4096], help="batch sizes B")
    physics.add_argument(
        "--centroid-sizes",
        type=int,
        nargs="*",
        default=[1, 64, 1024],
        help="batch sizes at which the (slow) centroid solver is also timed",
    )
    physics.add_argument("--wind", type=float, default=12.0, help="wind speed U10 (m/s)")
    physics.add_argument("--repeats", type=int, default=5, help="timed runs per measurement (median reported)")
    env = sub.add_parser("env", help="environment steps per second and memory")
    env.add_argument("--sizes", type=int, nargs="+", default=[1, 16, 256, 1024, 4096], help="batch sizes B")
    env.add_argument(
        "--centroid-sizes", type=int, nargs="*", default=[1, 16], help="batch sizes for the centroid solver"
    )
    channel = sub.add_parser("channel", help="env-steps/s of each channel model on each sea, in one run")
    channel.add_argument("--sizes", type=int, nargs="+", default=[16, 1024], help="batch sizes B")
    channel.add_argument("--lattices", nargs="+", default=[""], help='full, ocean: lattices "nodes:span" ("": default)')
    montecarlo = sub.add_parser("montecarlo", help="the full channel against the Monte Carlo reference")
    montecarlo.add_argument("--winds", type=float, nargs="+", default=[4.0, 12.0, 20.0], help="U10 (m/s)")
    montecarlo.add_argument("--seas", type=int, default=16, help="sea realisations (links) per wind")
    montecarlo.add_argument("--steps", type=int, default=20, help="steps of 0.05 s per sea")
    montecarlo.add_argument("--rays", type=int, default=2000, help="surface rays per link and step")
    montecarlo.add_argument("--facets", type=int, default=64, help="counting: unresolved-slope draws per surface ray")
    montecarlo.add_argument(
        "--reference", choices=("local", "counting"), default="local", help="the local estimate or the counting tracer"
    )
    montecarlo.add_argument("--offset", type=float, default=0.1, help="offset ratio")
    montecarlo.add_argument(
        "--lattices",
        nargs="+",
        default=[""],
        help='full channels "nodes:span"; "N:S:bound": no beam lattice',
    )
    evaluation = sub.add_parser("evaluate", help="the default evaluate.py work, batched vs one policy at a time")
    training = sub.add_parser(
        "training", help="train.py's frames/s (short, long, eager, compiled, under load) vs bare PyTorch and SB3"
    )
    training.add_argument("--updates", type=int, default=300, help="timed updates (median reported)")
    training.add_argument("--short-frames", type=int, default=3_200, help="frames of the short train.py runs")
    training.add_argument("--long-frames", type=int, default=32_000, help="frames of the long train.py runs")
    training.add_argument("--sb3-frames", type=int, default=4_000, help="timed Stable-Baselines3 frames")
    training.add_argument(
        "--threads", default="auto", type=_threads, help="torch threads of every run: auto (train.py's rule) or N"
    )
    training.add_argument("--no-load", action="store_false", dest="load", help="skip the runs beside a busy process")
    training.add_argument(
        "--override",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a train.py override for every run, SB3's included (repeatable), e.g. env/channel=single_path",
    )
    quality = sub.add_parser("quality", help="wall time to a greedy 0.95 of UB: ours vs Stable-Baselines3")
    quality.add_argument("--frames", type=int, default=40_000, help="frames of each of our runs at most")
    quality.add_argument("--flat-frames", type=int, default=160_000, help="the same on the flat-Snell base")
    quality.add_argument("--chunk", type=int, default=CHUNK, help="frames between two scorings of every pipeline")
    quality.add_argument("--sb3-frames", type=int, default=80_000, help="frames of each Stable-Baselines3 run at most")
    quality.add_argument(
        "--modes", nargs="+", choices=list(MODES), default=["compiled"], help="how our pipelines run: compiled, eager"
    )
    quality.add_argument("--seeds", nargs="+", type=int, default=[0], help="training seeds of every pipeline")
    pipelines, bases = known_names()
    quality.add_argument("--pipelines", nargs="+", choices=pipelines, help="the pipelines to run (default: all)")
    quality.add_argument("--bases", nargs="+", choices=bases, help="the bases to run on (default: both)")
    quality.add_argument(
        "--threads", type=_threads, default=None, help="torch threads of every pipeline, auto or N (default: every CPU)"
    )
    quality.add_argument("--out", type=Path, default=None, help="JSON output file (default outputs/bench/SUITE.json)")
    census = sub.add_parser("census", help="refraction points per link on the measured-slope sea (float64)")
    census.add_argument("--winds", type=float, nargs="+", default=[4.0, 12.0, 20.0], help="U10 (m/s)")
    census.add_argument("--offsets", type=float, nargs="+", default=[0.0, 0.1, 0.5], help="offset ratios")
    census.add_argument("--cutoffs", type=float, nargs="+", default=[10.0], help="wavenumber cutoffs k_c (rad/m)")
    census.add_argument("--links", type=int, default=16, help="sea realisations per point")
    census.add_argument("--times", type=float, nargs="+", default=[1.0, 7.0], help="instants per sea (s)")
    census.add_argument("--spacing", type=float, default=0.0, help="between Newton starts (m); 0: λ_c/4, ≤ 8 cm")
    census.add_argument("--out", type=Path, default=None, help="JSON output file (default outputs/bench/SUITE.json)")
    cutoff = sub.add_parser("cutoff", help="the local estimate's mean and scintillation as k_c rises (float64)")
    cutoff.add_argument("--winds", type=float, nargs="+", default=[4.0, 12.0, 20.0], help="U10 (m/s)")
    cutoff.add_argument("--cutoffs", type=float, nargs="+", default=[10.0, 40.0, 100.0], help="k_c (rad/m)")
    cutoff.add_argument("--seas", type=int, default=48, help="sea realisations per point")
    cutoff.add_argument("--times", type=float, nargs="+", default=[10.0, 10.7, 11.4, 12.1, 12.8, 13.5], help="s")
    cutoff.add_argument("--rays", type=int, default=2500, help="surface rays per link and instant")
    totals = sub.add_parser("summary", help="print the speed targets as ratios from the suites' JSON files")
    totals.add_argument("folder", type=Path, nargs="?", default=Path("outputs/bench"))
    controllers = sub.add_parser("controllers", help="step time the classical controllers and sensors add")
    controllers.add_argument("--batch", type=int, default=1024, help="batch size B")
    controllers.add_argument("--steps", type=int, default=50, help="steps per timed rollout")
    controllers.add_argument("--repeats", type=int, default=3, help="timed rollouts per policy (median reported)")
    for p in (physics, env, channel, montecarlo):
        p.add_argument("--dtype", choices=["float32", "float64"], default="float32")
    training.add_argument("--out", type=Path, default=None, help="JSON output file (default outputs/bench/SUITE.json)")
    for p in (physics, env, evaluation, controllers, channel, montecarlo, cutoff):
        p.add_argument("--device", choices=["auto", "cpu", "cuda"], default="auto")
        if p not in (montecarlo, cutoff):
            p.add_argument("--compile", action="store_true", help="evaluate the surface through torch.compile")
        p.add_argument("--out", type=Path, default=None, help="JSON output file (default outputs/bench/SUITE.json)")
    for name, p in sub.choices.items():
        if name != "summary":
            rounds = 3 if name in ROUNDS_JUDGED else 1
            p.add_argument(
                "--rounds", type=int, default=rounds, help=f"whole runs of the suite, in turn (default {rounds})"
            )
    args = parser.parse_args(argv)
    if args.suite != "summary" and args.rounds < 1:
        parser.exit(2, f"error: --rounds = {args.rounds} is out of range; allowed [1, ...)\n")
    if args.suite == "summary":
        print(summary(args.folder))
        return 0
    try:
        device = resolve_device(getattr(args, "device", "cpu"))
        sea = sea_state("jonswap", wind=args.wind) if args.suite == "physics" else None
    except ValueError as error:
        parser.exit(2, f"error: {error}\n")
    if args.suite in ("training", "quality") and not sb3_installed():
        print(SB3_MISSING, flush=True)
    records = []
    for index in range(args.rounds):  # each round the whole suite, both sides of each pair in it, in turn
        if args.rounds > 1:
            print(f"round {index + 1} of {args.rounds}", flush=True)
        records.append(_record(args, device, sea))
    record = records[0] if args.rounds == 1 else {"machine": records[0].get("machine"), "rounds": records}
    out = args.out or Path("outputs/bench") / f"{args.suite}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_json(out, record)
    print(f"\nwritten {out}")
    return 0


def _record(args: argparse.Namespace, device: torch.device, sea) -> dict:
    """One round of the suite ``args`` names: its record, its table printed."""
    if args.suite == "training":
        record = {"machine": machine(torch.device("cpu"), torch.float32)}
        record.update(
            bench_training(
                args.updates,
                args.short_frames,
                args.long_frames,
                args.sb3_frames,
                args.threads,
                args.load,
                tuple(args.override),
            )
        )
        print(training_table(record))
    elif args.suite == "quality":
        record = {"machine": machine(torch.device("cpu"), torch.float32)}
        record.update(
            bench_quality(
                args.frames,
                args.flat_frames,
                args.sb3_frames,
                args.modes,
                args.chunk,
                threads=args.threads,
                seeds=args.seeds,
                pipelines=args.pipelines,
                bases=args.bases,
            )
        )
        print(quality_table(record))
    elif args.suite == "census":
        print(census_table({"rows": []}))
        record = {"machine": machine(torch.device("cpu"), torch.float64)}
        record.update(bench_census(args.winds, args.offsets, args.cutoffs, args.links, args.times, args.spacing))
    elif args.suite == "evaluate":
        record = {"machine": machine(device, torch.float32), **bench_evaluate(args.device, args.compile)}
        print(evaluate_table(record))
    elif args.suite == "controllers":
        record = bench_controllers(args.batch, args.steps, args.repeats, args.compile, args.device)
        print(controllers_table(record))
    elif args.suite == "channel":
        print(f"channel benchmark: {device}, {'compiled' if args.compile else 'eager'} step\n\n{ENV_HEADER}")
        record = bench_channels(args.sizes, args.compile, args.device, args.dtype, args.lattices)
    elif args.suite == "cutoff":
        print(CUTOFF_HEADER)
        record = {"machine": machine(device, torch.float64)}
        record.update(bench_cutoff(args.winds, args.cutoffs, args.seas, args.times, args.rays, device))
    elif args.suite == "montecarlo":
        print(MONTECARLO_HEADER)
        record = {"machine": machine(device, getattr(torch, args.dtype))}
        dtype = getattr(torch, args.dtype)
        record.update(
            bench_montecarlo(
                args.winds,
                args.seas,
                args.steps,
                args.rays,
                args.facets,
                args.offset,
                device,
                dtype,
                args.reference,
                args.lattices,
            )
        )
        print("\n" + montecarlo_table(record))
    elif args.suite == "env":
        print(f"env benchmark: {device}, {'compiled' if args.compile else 'eager'} surface kernel\n\n{ENV_HEADER}")
        record = bench_env(args.sizes, args.centroid_sizes, args.compile, args.device, args.dtype)
    else:
        dtype = getattr(torch, args.dtype)
        record = bench_physics(args.sizes, args.centroid_sizes, args.repeats, device, dtype, sea, args.compile)
        print(physics_table(record))
    return record


def _threads(text: str) -> int | str:
    """``--threads``: ``auto`` or a count, checked as train.py checks ``threads``."""
    try:
        return check_threads(text if text == "auto" else int(text) if text.lstrip("-").isdigit() else text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


if __name__ == "__main__":
    from waterair.core.process import set_up_process

    set_up_process()  # the benchmarks' process as train.py's and evaluate.py's
    raise SystemExit(main())
