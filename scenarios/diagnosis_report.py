"""The diagnosis report: Markdown plus PNG figures (``impactqp diagnose --report OUT``).

Figures: ``jumps.png`` (measured, nominal-simulation and extended-simulation jumps per joint,
mean over each posture's trials), ``error_vs_speed.png`` (average error (26) of the nominal and
extended simulations and of the predictors against the reference speed) and
``predictor_errors.png`` (mean absolute error (25) per joint of every predictor and both
simulations). Every file is written atomically (``controller.measured.atomic``); other files in the
directory are kept.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic, write_text_atomic  # noqa: E402
from impactqp.sim.diagnosis import EXPLAINED_GAIN, Diagnosis  # noqa: E402

JOINTS = np.arange(1, 8)


def series(diagnosis: Diagnosis) -> dict[str, np.ndarray]:
    return {
        "measured": np.array([t.jump for t in diagnosis.trials]),
        "nominal sim": diagnosis.nominal_jumps,
        "extended sim": diagnosis.extended_jumps,
        **{m: p for m, p in diagnosis.predictions.items()},
    }


def absolute_errors(diagnosis: Diagnosis) -> dict[str, np.ndarray]:
    """|e| of eq. (25) (trials x 7) of both simulations and every predictor."""
    data = series(diagnosis)
    measured = data.pop("measured")
    return {name: np.abs(jumps - measured) for name, jumps in data.items()}


def save(fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110, format="png")
    plt.close(fig)


def plot_jumps(diagnosis: Diagnosis, path: Path) -> None:
    postures = sorted({t.posture or "unknown" for t in diagnosis.trials})
    data = series(diagnosis)
    fig, axes = plt.subplots(1, len(postures), figsize=(5 * len(postures), 3.6), squeeze=False)
    for ax, posture in zip(axes[0], postures):
        rows = [i for i, t in enumerate(diagnosis.trials) if (t.posture or "unknown") == posture]
        for k, name in enumerate(("measured", "nominal sim", "extended sim")):
            ax.bar(JOINTS + (k - 1) * 0.27, data[name][rows].mean(axis=0), width=0.27, label=name)
        ax.set_title(f"{posture} ({len(rows)} trials)")
        ax.set_xlabel("joint")
        ax.set_xticks(JOINTS)
        ax.axhline(0.0, color="k", lw=0.5)
    axes[0][0].set_ylabel("mean jump (rad/s)")
    axes[0][0].legend(fontsize=8)
    save(fig, path)


def plot_error_vs_speed(diagnosis: Diagnosis, path: Path) -> None:
    speeds = np.array([t.reference_speed for t in diagnosis.trials])
    levels = np.unique(speeds)
    fig, ax = plt.subplots(figsize=(6, 4))
    for name, errors in absolute_errors(diagnosis).items():
        average = errors.mean(axis=1)
        ax.plot(levels, [average[speeds == v].mean() for v in levels], "o-", label=name)
    ax.set_xlabel("reference normal speed (m/s)")
    ax.set_ylabel("average error, eq. (26) (rad/s)")
    ax.legend(fontsize=8)
    save(fig, path)


def plot_predictor_errors(diagnosis: Diagnosis, path: Path) -> None:
    errors = absolute_errors(diagnosis)
    fig, ax = plt.subplots(figsize=(7, 4))
    width = 0.8 / len(errors)
    for k, (name, error) in enumerate(errors.items()):
        ax.bar(JOINTS + (k - len(errors) / 2 + 0.5) * width, error.mean(axis=0), width, label=name)
    ax.set_xlabel("joint")
    ax.set_ylabel("mean |error|, eq. (25) (rad/s)")
    ax.set_xticks(JOINTS)
    ax.legend(fontsize=8)
    save(fig, path)


def table_by_condition(diagnosis: Diagnosis) -> list[str]:
    """The paper's Table I on the user's data: average error (26) per posture and condition."""
    errors = absolute_errors(diagnosis)
    conditions = sorted(
        {(t.posture or "unknown", t.reference_speed, t.tangential_speed) for t in diagnosis.trials}
    )
    names = list(errors)
    lines = ["| posture | v_n (m/s) | v_t (m/s) | " + " | ".join(names) + " |", "|" + "---|" * (3 + len(names))]
    for posture, vn, vt in conditions:
        rows = [
            i for i, t in enumerate(diagnosis.trials)
            if (t.posture or "unknown", t.reference_speed, t.tangential_speed) == (posture, vn, vt)
        ]
        cells = [f"{errors[n][rows].mean():.4f}" for n in names]
        lines.append(f"| {posture} | {vn:.3f} | {vt:.3f} | " + " | ".join(cells) + " |")
    return lines


def markdown(diagnosis: Diagnosis) -> str:
    s = diagnosis.summary()
    a = s["analysis"]
    lines = [
        "# Impact diagnosis",
        "",
        s["message"],
        "",
        f"- trials used: {s['trials']}, skipped: {len(s['skipped'])}",
        f"- cause: **{s['cause']}** (explained: {s['explained']}, threshold {100 * EXPLAINED_GAIN:.0f} % held-out gain)",
        f"- parameters: `{s['parameters']}`",
        f"- average error (26), held-out: nominal simulation {s['baseline_error']:.4f} rad/s, "
        f"extended simulation {s['extended_error']:.4f} rad/s, gain {100 * s['gain']:.1f} %",
        "",
        "## What the nominal simulation gets wrong",
        "",
        "| joint | mean error (25) | mean abs error | sim / measured | share of error |",
        "|---|---|---|---|---|",
    ]
    for j in range(7):
        lines.append(
            f"| {j + 1} | {a['per_joint_mean_error'][j]:+.4f} | {a['per_joint_mean_abs_error'][j]:.4f} | "
            f"{a['per_joint_sim_to_measured_ratio'][j]:.3f} | {100 * a['per_joint_error_share'][j]:.1f} % |"
        )
    lines += [
        "",
        f"Average error (26) grows by {a['error_vs_speed_slope']:.3f} (rad/s) per m/s of reference speed. "
        "A sim / measured ratio above 1 means the simulation overshoots that joint's jump.",
        "",
        "## Candidate causes (cross-validated over trials)",
        "",
        "| cause | held-out error (rad/s) | gain | parameters |",
        "|---|---|---|---|",
    ]
    for c in sorted(s["candidates"], key=lambda c: -c["gain"]):
        lines.append(f"| {c['cause']} | {c['heldout_error']:.4f} | {100 * c['gain']:.1f} % | `{c['parameters']}` |")
    lines += ["", "## Predictors and simulations per condition (average error (26), rad/s)", ""]
    lines += table_by_condition(diagnosis)
    lines += ["", "| predictor | own impulse | measured impulse |", "|---|---|---|"]
    for m, e in s["predictors"].items():
        fed = s["predictors_measured_impulse"].get(m)
        lines.append(f"| {m} | {e:.4f} | {'' if fed is None else f'{fed:.4f}'} |")
    if s["skipped"]:
        lines += ["", "## Skipped", ""] + [f"- {x['id']}: {x['reason']}" for x in s["skipped"]]
    lines += [
        "",
        "## Figures",
        "",
        "![jumps](jumps.png)",
        "",
        "![error vs speed](error_vs_speed.png)",
        "",
        "![errors per joint](predictor_errors.png)",
        "",
    ]
    return "\n".join(lines)


def write_report(diagnosis: Diagnosis, out: str | Path) -> Path:
    """Write ``report.md`` and the three figures into the directory ``out`` (created when
    missing), each file atomically; other files in ``out`` are left alone."""
    out = Path(out)
    for name, plot in (
        ("jumps.png", plot_jumps),
        ("error_vs_speed.png", plot_error_vs_speed),
        ("predictor_errors.png", plot_predictor_errors),
    ):
        write_atomic(out / name, lambda tmp, plot=plot: plot(diagnosis, tmp))
    return write_text_atomic(out / "report.md", markdown(diagnosis))
