"""Evaluation figures: the paper's "gain over time", "average gain" and "σ²_diff", the sweeps, the BER and outage.

Each function takes an :class:`waterair.evaluation.Evaluation` and writes one PNG; a figure whose
scenario was not evaluated is skipped. Every policy has its own colour, marker and line style (fixed
per baseline, so that the figures of one report read together), and legends sit below the plots,
outside the data.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from waterair.evaluation.divergence import best_divergences  # noqa: E402
from waterair.physics.link import link_performance  # noqa: E402

STYLES = {
    "bound": ("black", "o", (0, (6, 3)), 1.6),
    "tracking": ("tab:purple", "v", ":", 1.4),
    "prediction_bound": ("mediumorchid", "2", (0, (3, 1, 1, 1)), 1.5),
    "beacon_tracker": ("darkgoldenrod", "X", (0, (8, 2)), 1.7),
    "beacon_predictor": ("teal", "H", (0, (6, 1, 1, 1, 1, 1)), 1.7),
    "kalman_tracker": ("navy", "1", (0, (10, 2, 1, 2)), 1.7),
    "aoa_tracker": ("tab:pink", "p", (0, (5, 1)), 1.6),
    "intensity_dither": ("tab:brown", "d", (0, (3, 1, 1, 1, 1, 1)), 1.4),
    "flat_snell": ("tab:green", "s", "--", 1.4),
    "straight_facing": ("tab:orange", "^", "-.", 1.3),
    "no_alignment": ("tab:gray", "x", (0, (1, 1)), 1.2),
}
"""Colour, marker, line style and width of the upper bound and each baseline: every policy differs in all four."""
SENSING_STYLES = {
    "prediction_bound": ("plum", "3", (0, (3, 1, 1, 1, 1, 1)), 1.5),
    "beacon_tracker": ("olivedrab", "8", (0, (8, 2, 2, 2)), 1.7),
    "beacon_predictor": ("darkslategray", "+", (0, (6, 2, 1, 2, 1, 2)), 1.7),
    "kalman_tracker": ("steelblue", "4", (0, (10, 1, 2, 1)), 1.7),
    "aoa_tracker": ("darkmagenta", "<", (0, (2, 2)), 1.6),
    "intensity_dither": ("saddlebrown", ">", (0, (4, 2, 1, 2)), 1.4),
}
"""The classical controllers and the prediction bound run again with a learned policy's own sensing (labelled with
it)."""
LEARNED_STYLES = (
    ("tab:blue", "D", "-", 2.2),
    ("tab:red", "P", "-", 2.2),
    ("tab:cyan", "*", "-", 2.2),
    ("tab:olive", "h", "-", 2.2),
)
"""Learned policies: thick, told apart by colour and marker; past these four, each round of them by its dashes
(:data:`LEARNED_DASHES`)."""
LEARNED_DASHES = ("-", (0, (6, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))
"""The learned styles' line styles, one per round of :data:`LEARNED_STYLES`: sixteen learned policies apart."""
BER_FLOOR = 1e-12
"""BER figures draw a BER below it (down to 0 in float64 on a well aligned step) at it."""
MARKS_PER_TRACE = 12
"""Markers along a time trace (staggered per policy so that overlapping lines stay distinguishable)."""


def evaluation_figures(result, out: Path) -> list[Path]:
    """Every evaluation figure of ``result`` whose scenario exists, written into ``out``."""
    names = {s.name for s in result.scenarios}
    written = []
    if "S1" in names:
        written.append(gain_vs_time(result, out / "gain_vs_time.png"))
        written.append(ber_vs_time(result, out / "ber_vs_time.png"))
    if "S2" in names:
        written.append(gain_vs_sweep(result, "S2", out / "gain_vs_offset.png"))
        written.append(sigma_diff_vs_offset(result, out / "sigma_diff_vs_offset.png"))
        written.append(outage_vs_sweep(result, "S2", out / "outage_vs_offset.png"))
    if "S3" in names:
        written.append(gain_vs_sweep(result, "S3", out / "gain_vs_wind.png"))
        written.append(outage_vs_sweep(result, "S3", out / "outage_vs_wind.png"))
    if "S4" in names:
        written.append(gain_vs_sweep(result, "S4", out / "gain_vs_azimuth.png"))
    if "S5" in names:
        winds = dict.fromkeys(w for w, _, _ in _scenario(result, "S5").points)
        written += [rate_vs_divergence(result, w, out / f"rate_vs_divergence_{w:g}ms.png") for w in winds]
        if result.power_rows:
            written.append(outage_vs_power(result, out / "outage_vs_power.png"))
    if "S6" in names:
        written.append(rate_vs_speed(result, out / "rate_vs_speed.png"))
    if "S7" in names:
        written.append(rate_vs_period(result, out / "rate_vs_period.png"))
    return written


def gain_vs_time(result, path: Path) -> Path:
    """S1: G(t) of every policy on one sea realisation, and the mean over all realisations."""
    traces = result.traces["S1"]

    def finish(ax) -> None:
        ax.set_ylabel("channel gain G (m⁻²)")
        ax.grid(alpha=0.3)

    gains = {policy["label"]: traces[policy["label"]]["gain"][:, 0] for policy in result.policies}
    return _over_time(result, path, gains, None, finish, _scenario(result, "S1").title)


def ber_vs_time(result, path: Path) -> Path:
    """S1: the link's BER(t) of every policy on one sea realisation, and the mean over all realisations."""
    traces = result.traces["S1"]

    def finish(ax) -> None:
        ax.axhline(result.link.fec_limit, color="crimson", linewidth=1.0, label="FEC limit")
        ax.set_yscale("log")
        ax.set_ylim(BER_FLOOR / 3, 1.0)
        ax.set_ylabel("bit error rate")
        ax.grid(alpha=0.3, which="both")

    bers = {
        policy["label"]: link_performance(traces[policy["label"]]["gain"][:, 0].double(), result.link).ber
        for policy in result.policies
    }
    link = f"{result.link.bit_rate / 1e6:g} Mbit/s OOK, {result.link.power_w * 1e3:g} mW"
    drawn = f"outage above the FEC limit; a BER below {BER_FLOOR:g} drawn at it"
    title = f"{_scenario(result, 'S1').title}\n{link}: {drawn}"
    return _over_time(result, path, bers, BER_FLOOR, finish, title)


def _over_time(result, path: Path, values: dict, floor: float | None, finish, title: str) -> Path:
    """S1 traces ``values[label]`` ``[R, T]``: the first realisation above, the mean below (each
    clamped at ``floor`` when given); ``finish(ax)`` labels each axis."""
    scenario = _scenario(result, "S1")
    time = [result.dt * (k + 1) for k in range(scenario.steps)]
    spacing = max(1, scenario.steps // MARKS_PER_TRACE)
    fig, axes = plt.subplots(2, 1, figsize=(9, 7.5), sharex=True)
    for ax, subtitle, reduce in (
        (axes[0], "one sea realisation (the first)", lambda v: v[0]),
        (axes[1], f"mean over {scenario.realisations} realisations", lambda v: v.double().mean(0)),
    ):
        for index, policy in enumerate(result.policies):
            colour, marker, style, width = _style(result, policy)
            trace = reduce(values[policy["label"]])
            trace = trace if floor is None else trace.clamp(min=floor)
            ax.plot(time, trace, color=colour, linestyle=style, linewidth=width,
                    marker=marker, markersize=5, markevery=(index * spacing // len(result.policies), spacing),
                    label=policy["label"])  # fmt: skip
        finish(ax)
        ax.set_title(subtitle, fontsize=10)
    axes[1].set_xlabel("time (s)")
    fig.suptitle(title)
    return _save_with_legend(fig, axes[0], path)


def outage_vs_sweep(result, name: str, path: Path) -> Path:
    """S2 or S3: the link's outage probability (BER above the FEC limit) per point, with its interval."""
    scenario = _scenario(result, name)
    x = _axis_values(scenario)
    fig, ax = plt.subplots(figsize=(8, 5.5))
    for policy in result.policies:
        rows = _rows(result, name, policy["label"])
        colour, marker, style, width = _style(result, policy)
        ax.plot(x, [r["outage"] for r in rows], color=colour, marker=marker, linestyle=style, linewidth=width,
                label=policy["label"])  # fmt: skip
        ax.fill_between(x, [r["outage_lo"] for r in rows], [r["outage_hi"] for r in rows], color=colour, alpha=0.12)
    ax.set_xlabel(_axis_label(scenario))
    ax.set_ylabel(f"outage probability P(BER > {result.link.fec_limit:g})")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(f"{scenario.title}: the link's outage at {result.link.bit_rate / 1e6:g} Mbit/s (lower is better)",
                 fontsize=10)  # fmt: skip
    ax.grid(alpha=0.3)
    return _save_with_legend(fig, ax, path)


def gain_vs_sweep(result, name: str, path: Path) -> Path:
    """S2, S3 or S4: mean gain with its interval (top) and the ratio to the upper bound (bottom) per point."""
    scenario = _scenario(result, name)
    x = _axis_values(scenario)
    fig, axes = plt.subplots(2, 1, figsize=(8, 7.5), sharex=True)
    for policy in result.policies:
        rows = _rows(result, name, policy["label"])
        colour, marker, style, width = _style(result, policy)
        mean = [r["mean_gain"] for r in rows]
        error = [[r["mean_gain"] - r["mean_gain_lo"] for r in rows], [r["mean_gain_hi"] - r["mean_gain"] for r in rows]]
        axes[0].errorbar(x, mean, yerr=error, color=colour, marker=marker, linestyle=style, linewidth=width,
                         capsize=3, label=policy["label"])  # fmt: skip
        axes[1].plot(x, [r["ratio_to_ub"] for r in rows], color=colour, marker=marker, linestyle=style, linewidth=width)
    axes[0].set_ylabel("mean channel gain (m⁻²)")
    axes[1].set_ylabel("mean G / mean G_UB")
    axes[1].set_ylim(0.0, 1.05)
    axes[1].set_xlabel(_axis_label(scenario))
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle(f"{scenario.title}\n{scenario.realisations} realisations × {scenario.steps * result.dt:g} s, 95 % CI")
    return _save_with_legend(fig, axes[0], path)


def sigma_diff_vs_offset(result, path: Path) -> Path:
    """S2: σ²_diff = var(G_UB − G) per offset, log scale (the upper bound, 0 by definition, is left out)."""
    scenario = _scenario(result, "S2")
    x = _axis_values(scenario)
    fig, ax = plt.subplots(figsize=(8, 5))
    for policy in result.policies:
        if policy["kind"] == "bound":
            continue
        rows = _rows(result, "S2", policy["label"])
        colour, marker, style, width = _style(result, policy)
        values = [r["sigma2_diff"] for r in rows]
        ax.plot(x, values, color=colour, marker=marker, linestyle=style, linewidth=width, label=policy["label"])
        ax.fill_between(x, [r["sigma2_diff_lo"] for r in rows], [r["sigma2_diff_hi"] for r in rows], color=colour,
                        alpha=0.12)  # fmt: skip
    ax.set_yscale("log")
    ax.set_xlabel(_axis_label(scenario))
    ax.set_ylabel("σ²_diff = var(G_UB − G) (m⁻⁴)")
    ax.set_title(f"{scenario.title}: stability (lower is better, read with the gain)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    return _save_with_legend(fig, ax, path)


def rate_vs_divergence(result, wind: float, path: Path) -> Path:
    """S5 at one wind: mean bit rate (top) and the rate held 99 % of the time (bottom) against the divergence,
    one column per offset, the best divergence of each policy (highest mean rate) ringed."""
    scenario = _scenario(result, "S5")
    offsets = [o for w, o, _ in scenario.points if w == wind]
    x = [d * 1e3 for d in scenario.divergences]
    best = {(b["offset_ratio"], b["policy"]): b for b in best_divergences(result.rows, scenario) if b["wind"] == wind}
    # one offset still gets the width of the title and a four-column legend
    fig, axes = plt.subplots(2, len(offsets), figsize=(max(5.2 * len(offsets), 10.0), 7.5), sharex=True, squeeze=False)
    for column, offset in enumerate(offsets):
        for policy in result.policies:
            rows = [result.row("S5", policy["label"], (wind, offset, 0.0), d) for d in scenario.divergences]
            colour, marker, style, width = _style(result, policy)
            kw = dict(color=colour, marker=marker, linestyle=style, linewidth=width)
            axes[0, column].plot(x, [r["rate"] / 1e6 for r in rows], label=policy["label"], **kw)
            axes[1, column].plot(x, [r["rate_held"] / 1e6 for r in rows], **kw)
            top = best[(offset, policy["label"])]
            axes[0, column].plot(top["divergence"] * 1e3, top["rate"] / 1e6, marker="o", markersize=13,
                                 markerfacecolor="none", markeredgecolor=colour, markeredgewidth=1.6)  # fmt: skip
        axes[0, column].set_title(f"offset {offset:.0%}", fontsize=10)
        axes[1, column].set_xlabel("beam divergence ω_D (mrad)")
    axes[0, 0].set_ylabel("mean bit rate at the\nFEC limit (Mbit/s)")  # two lines: one ran into the other's
    axes[1, 0].set_ylabel("bit rate held 99 %\nof the time (Mbit/s)")
    for ax in axes.flat:
        ax.set_xscale("log")
        ax.set_xticks(x, [f"{v:g}" for v in x])
        ax.minorticks_off()
        ax.grid(alpha=0.3)
    link = result.link_of("S5", scenario.divergences[0])
    fig.suptitle(f"S5: link rate against beam divergence, U10 = {wind:g} m/s ({link.power_w * 1e3:g} mW; "
                 f"rings: each policy's best divergence)\n{scenario.realisations} realisations × "
                 f"{scenario.steps * result.dt:g} s")  # fmt: skip
    return _save_with_legend(fig, axes[0, 0], path)


def outage_vs_power(result, path: Path) -> Path:
    """S5's power sweep: outage against transmit power, one panel per offset, with its interval."""
    scenario = _scenario(result, "S5")
    sweep = scenario.power_sweep
    offsets = list(dict.fromkeys(r["offset_ratio"] for r in result.power_rows))
    fig, axes = plt.subplots(1, len(offsets), figsize=(5.2 * len(offsets), 5.5), squeeze=False)
    for column, offset in enumerate(offsets):
        ax = axes[0, column]
        for policy in result.policies:
            rows = [r for r in result.power_rows if r["policy"] == policy["label"] and r["offset_ratio"] == offset]
            x = [r["power_w"] * 1e3 for r in rows]
            colour, marker, style, width = _style(result, policy)
            ax.plot(x, [r["outage"] for r in rows], color=colour, marker=marker, linestyle=style, linewidth=width,
                    label=policy["label"])  # fmt: skip
            ax.fill_between(x, [r["outage_lo"] for r in rows], [r["outage_hi"] for r in rows], color=colour,
                            alpha=0.12)  # fmt: skip
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=1e-3)
        ax.set_ylim(0.0, 1.05)
        ax.set_xlabel("transmit power (mW)")
        ax.set_title(f"offset {offset:.0%}", fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("outage probability P(BER > FEC limit)")
    fig.suptitle(f"S5: outage against transmit power, U10 = {sweep.wind:g} m/s, ω_D = {sweep.divergence * 1e3:g} mrad\n"
                 "(a floor that more power cannot lift is light that never arrives)")  # fmt: skip
    return _save_with_legend(fig, axes[0, 0], path)


HELD = "tracking_rate_held"
"""What S6's and S7's figures draw: the rate held 99 % of the time once tracking (after the acquisition's start-up)."""


def rate_vs_speed(result, path: Path) -> Path:
    """S6: the rate held 99 % of the tracking's time (:data:`HELD`) against the drone's speed across the link (top;
    faint: parked on the same crossing) and against its attitude jitter hovering (bottom), a column per wind."""
    scenario = _scenario(result, "S6")
    winds = [w for w, _, _ in scenario.points]
    fig, axes = plt.subplots(2, len(winds), figsize=(max(5.2 * len(winds), 10.0), 7.5), squeeze=False)
    attitude = max(scenario.settings, key=lambda s: s.speed).attitude  # the speeds' attitude (the fastest's)
    for column, wind in enumerate(winds):
        rows = [r for r in result.rows if r["scenario"] == "S6" and r["wind"] == wind]
        for policy in result.policies:
            mine = [r for r in rows if r["policy"] == policy["label"]]
            colour, marker, style, width = _style(result, policy)
            kw = dict(color=colour, marker=marker, linestyle=style, linewidth=width)
            along = sorted((r for r in mine if _at_attitude(r, attitude)), key=lambda r: r["drone_speed"])
            moving = [r for r in along if not r["parked"] or r["drone_speed"] == 0]
            parked = [r for r in along if r["parked"] or r["drone_speed"] == 0]
            for ax, part, x, extra in ((axes[0, column], moving, "drone_speed", {"label": policy["label"]}),
                                       (axes[0, column], parked, "drone_speed", {"alpha": 0.3}),
                                       (axes[1, column], sorted((r for r in mine if r["drone_speed"] == 0),
                                                               key=lambda r: r["drone_attitude_deg"]),
                                        "drone_attitude_deg", {})):  # fmt: skip
                xs = [r[x] for r in part]
                ax.plot(xs, [r[HELD] / 1e6 for r in part], **kw, **extra)
                if not extra.get("alpha"):
                    ax.fill_between(xs, [r[f"{HELD}_lo"] / 1e6 for r in part],
                                    [r[f"{HELD}_hi"] / 1e6 for r in part], color=colour, alpha=0.08)  # fmt: skip
        axes[0, column].set_title(f"U10 = {wind:g} m/s", fontsize=10)
        axes[0, column].set_xlabel("drone speed across the link (m/s)")
        axes[1, column].set_xlabel("σ of the drone's roll and pitch, hovering (deg)")
    axes[0, 0].set_ylabel("bit rate held 99 % of\nthe tracking (Mbit/s)")
    axes[1, 0].set_ylabel("bit rate held 99 % of\nthe tracking (Mbit/s)")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    link = result.link_of("S6", scenario.divergences[0])
    fig.suptitle(f"{scenario.title} ({link.power_w * 1e3:g} mW)\nfaint: parked on the same crossing; "
                 f"{scenario.realisations} realisations × {scenario.steps * result.dt:g} s")  # fmt: skip
    return _save_with_legend(fig, axes[0, 0], path)


def _at_attitude(row: dict, attitude: float | None) -> bool:
    return attitude is None or abs(row["drone_attitude_deg"] - math.degrees(attitude)) < 1e-9


def rate_vs_period(result, path: Path) -> Path:
    """S7: the rate held 99 % of the tracking's time (:data:`HELD`) against the loop period, a panel per actuator."""
    scenario = _scenario(result, "S7")
    rows = [r for r in result.rows if r["scenario"] == "S7"]
    actuators = list(dict.fromkeys(r["actuator"] for r in rows))
    fig, axes = plt.subplots(1, len(actuators), figsize=(max(4.2 * len(actuators), 10.0), 5.2), squeeze=False,
                             sharey=True)  # fmt: skip
    for column, actuator in enumerate(actuators):
        ax = axes[0, column]
        for policy in result.policies:
            mine = sorted((r for r in rows if r["policy"] == policy["label"] and r["actuator"] == actuator),
                          key=lambda r: r["dt"])  # fmt: skip
            xs = [r["dt"] * 1e3 for r in mine]
            colour, marker, style, width = _style(result, policy)
            ax.plot(xs, [r[HELD] / 1e6 for r in mine], color=colour, marker=marker, linestyle=style,
                    linewidth=width, label=policy["label"])  # fmt: skip
            ax.fill_between(xs, [r[f"{HELD}_lo"] / 1e6 for r in mine], [r[f"{HELD}_hi"] / 1e6 for r in mine],
                            color=colour, alpha=0.08)  # fmt: skip
        ax.set_xscale("log")
        ax.set_xticks(xs, [f"{v:g}" for v in xs])
        ax.minorticks_off()
        ax.set_title(actuator, fontsize=10)
        ax.set_xlabel("loop period env.dt (ms)")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("bit rate held 99 % of\nthe tracking (Mbit/s)")
    seconds = scenario.settings[0].steps * scenario.settings[0].dt
    fig.suptitle(f"{scenario.title}\n{scenario.realisations} realisations × {seconds:g} s")
    return _save_with_legend(fig, axes[0, 0], path)


def _scenario(result, name: str):
    return next(s for s in result.scenarios if s.name == name)


def _rows(result, name: str, label: str) -> list[dict]:
    scenario = _scenario(result, name)
    return [result.row(name, label, point) for point in scenario.points]


def _axis_values(scenario) -> list[float]:
    index = ("wind", "offset_ratio", "offset_azimuth_deg").index(scenario.axis)
    return [point[index] * (100.0 if index == 1 else 1.0) for point in scenario.points]


def _axis_label(scenario) -> str:
    return {
        "offset_ratio": "horizontal offset (% of the vertical distance)",
        "wind": "wind U10 (m/s)",
        "offset_azimuth_deg": "drone azimuth from the wind direction (deg)",
    }[scenario.axis]


def _style(result, policy: dict) -> tuple:
    """Colour, marker, line style and width of a policy."""
    if policy["kind"] == "bound":
        return STYLES["bound"]
    if policy["kind"] == "baseline":
        name = policy.get("baseline", policy["label"])
        styles = STYLES if policy["label"] == name else SENSING_STYLES
        return styles.get(name, ("tab:olive", "1", "-", 1.2))
    learned = [p["label"] for p in result.policies if p["kind"] == "learned"]
    index = learned.index(policy["label"])
    colour, marker, _, width = LEARNED_STYLES[index % len(LEARNED_STYLES)]
    return colour, marker, LEARNED_DASHES[index // len(LEARNED_STYLES) % len(LEARNED_DASHES)], width


def _save_with_legend(fig, ax, path: Path) -> Path:
    """Save ``fig`` with the legend of ``ax`` below every plot, outside the data, every label inside the image (long
    ones, a controller's sensing spelled out, in three columns)."""
    handles, labels = ax.get_legend_handles_labels()
    columns = 4 if max((len(label) for label in labels), default=0) <= 24 else 3
    rows = -(-len(labels) // columns)
    fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), columns), fontsize=8, frameon=False,
               handlelength=3.5)  # fmt: skip
    fig.tight_layout(rect=(0, 0.035 * rows + 0.01, 1, 1))
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
