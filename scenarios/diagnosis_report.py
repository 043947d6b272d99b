"""The diagnosis report: Markdown plus PNG figures (``impactqp diagnose --report OUT``).

Figures: ``jumps.png`` (measured, nominal-simulation and extended-simulation jumps per joint,
mean over each posture's trials, one y scale for all postures), ``error_vs_speed.png`` (average
error (26) of the nominal and extended simulations and of the predictors against the reference
speed, mean over the trials at each speed) and ``predictor_errors.png`` (mean absolute error
(25) per joint of every predictor and both simulations over all trials). Every file is written
atomically (``controller.measured.atomic``); other files in the directory are kept.

Numbers are written as a person reads them (``scenarios.readable``): plant parameters grouped
as the diagnosis fits them, booleans as ``true`` / ``false``. The ratio of simulated to measured
jump of a joint is left out when the measured jump is near zero: its root mean square over the
trials below ``NEAR_ZERO_STDS`` times the noise std of a jump (:func:`jump_noise_std`), where
the ratio divides by noise.

What it means for the user (:func:`feasible_speeds`): for each named posture of the data, the
highest feasible contact speed simulated with the nominal plant and with the extended plant
(the diagnosed causes), beside the CRB closed form (``scenarios.max_speed_search``), and which
of them to trust (:func:`trusted_speed_text`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dataclasses import dataclass  # noqa: E402

from impactqp.controller.measured.atomic import write_atomic, write_text_atomic  # noqa: E402
from impactqp.controller.measured.impact import POST_HALF_WIDTH, PRE_SAMPLES  # noqa: E402
from impactqp.controller.model.max_speed import DEFAULT_IMPACT_DURATION  # noqa: E402
from impactqp.scenarios.max_speed_search import DEFAULT_TOLERANCE, MaxSpeedSearch  # noqa: E402
from impactqp.sim.diagnosis import EXPLAINED_GAIN, STEP_GAIN, Diagnosis, interval_text  # noqa: E402
from impactqp.sim.diagnosis.intervals import open_side_text  # noqa: E402
from impactqp.sim.diagnosis.noise import BLOCKS  # noqa: E402
from impactqp.sim.plant import PlantParameters  # noqa: E402

from .readable import boolean, number, parameters_text  # noqa: E402

NEAR_ZERO_STDS = 3.0
FIGURE_DPI = 110
JUMPS_INCHES = (5.0, 4.0)
"""The jumps figure's size per posture (one panel each), inches."""
ERROR_VS_SPEED_INCHES = (6.0, 4.0)
PREDICTOR_ERRORS_INCHES = (7.0, 4.0)
PIXEL_BYTES = 4
"""Bytes of a pixel before compression (RGBA): PNG stores a figure's pixels in fewer, plus a few
dozen bytes of headers."""
TEXT_BYTES = 65_536
TEXT_BYTES_PER_TRIAL = 4096
"""report.md, estimated: its fixed sections, and per trial its rows (residual, jumps, speeds)."""


def report_bytes(postures: int, trials: int) -> float:
    """An estimate of the size of ``write_report``'s files for a dataset of ``trials`` trials at
    ``postures`` postures: each figure's pixels (its size in inches times FIGURE_DPI, in both
    directions) at PIXEL_BYTES, and the text's TEXT_BYTES plus TEXT_BYTES_PER_TRIAL per trial."""
    sizes = ((JUMPS_INCHES[0] * max(postures, 1), JUMPS_INCHES[1]), ERROR_VS_SPEED_INCHES, PREDICTOR_ERRORS_INCHES)
    pixels = sum(width * height for width, height in sizes) * FIGURE_DPI**2
    return PIXEL_BYTES * pixels + TEXT_BYTES + TEXT_BYTES_PER_TRIAL * trials


@dataclass(frozen=True)
class FeasibleSpeed:
    """Highest feasible contact speed (m/s) of one posture: CRB closed form, and simulated with
    the nominal and with the extended (diagnosed) plant."""

    posture: str
    crb_closed_form: float
    nominal_plant: float
    extended_plant: float

    def sentence(self) -> str:
        """One sentence; "not ..." only when the two answers differ at the printed precision."""
        extended, nominal = f"{self.extended_plant:.3f}", f"{self.nominal_plant:.3f}"
        if extended == nominal:
            return (
                f"At {self.posture}, your robot can hit at {extended} m/s: the nominal simulation's answer "
                f"holds with the diagnosed plant (CRB closed form {self.crb_closed_form:.3f} m/s)."
            )
        return (
            f"At {self.posture}, your robot can hit at {extended} m/s, not {nominal} m/s (the nominal "
            f"simulation's answer; CRB closed form {self.crb_closed_form:.3f} m/s)."
        )

    def to_json(self) -> dict:
        return {
            "posture": self.posture,
            "crb_closed_form": self.crb_closed_form,
            "nominal_plant": self.nominal_plant,
            "extended_plant": self.extended_plant,
        }


def feasible_speeds(
    diagnosis: Diagnosis,
    nominal: PlantParameters | None = None,
    *,
    postures: list[str] | None = None,
    jobs: int = 1,
    tolerance: float = DEFAULT_TOLERANCE,
    progress: bool = False,
) -> list[FeasibleSpeed]:
    """For each named posture of the diagnosed trials (trials without a named posture are left
    out; only ``postures`` when given), the simulated highest feasible speed with ``nominal`` and
    with the extended plant, and the CRB closed form at the contact posture (``MaxSpeedSearch``),
    for the diagnosed robot and tool."""
    nominal = nominal or PlantParameters()
    choice = diagnosis.choice
    names = sorted({t.posture for t in diagnosis.trials if t.posture in choice.robot.postures})
    if postures is not None:
        names = [n for n in names if n in postures]
    rows = []
    for name in names:
        reports = [
            MaxSpeedSearch(
                choice.posture(name), diagnosis.surface, plant, jobs=jobs, tolerance=tolerance, progress=progress,
                choice=choice,
            ).run()
            for plant in (nominal, diagnosis.extended_plant)
        ]
        rows.append(
            FeasibleSpeed(
                name, reports[1].predicted["crb"].speed, reports[0].simulated_max_speed, reports[1].simulated_max_speed
            )
        )
    return rows


def trusted_speed_text(diagnosis: Diagnosis, speeds: list[FeasibleSpeed]) -> str:
    """Which highest feasible speed to trust, and why: the simulation with the extended plant when
    the diagnosed causes explain the measured jumps, else the nominal simulation; never the
    closed form alone, which knows only the rigid nominal model (no drive, servo or contact
    dynamics) and assumes the impact duration."""
    if diagnosis.explained:
        named = " + ".join(diagnosis.causes)
        which, column = "the extended simulation", "extended_plant"
        why = (
            f"the diagnosed causes ({named}) explain the measured jumps, and only the simulation with them "
            "reproduces what the measured impacts showed"
        )
    else:
        which, column = "the nominal simulation", "nominal_plant"
        why = "no candidate cause explains the measured jumps, so the extended plant is no better than the nominal one"
    text = (
        f"Trust {which}: {why}. The CRB closed form knows only the rigid nominal model (no drive, servo or "
        f"contact dynamics) and assumes a {1e3 * DEFAULT_IMPACT_DURATION:g} ms impact, so it is an estimate."
    )
    for row in speeds:
        trusted = getattr(row, column)
        side = "above" if row.crb_closed_form > trusted else "below"
        consequence = "would hit too fast" if side == "above" else "is conservative"
        text += (
            f" At {row.posture} the closed form ({row.crb_closed_form:.3f} m/s) is {side} the trusted "
            f"{trusted:.3f} m/s: relying on it {consequence}."
        )
    return text


def jump_noise_std(diagnosis: Diagnosis) -> np.ndarray:
    """Noise std (rad/s) of a measured jump per joint. The per-sample velocity noise sigma is
    read from each trial's samples before the jump window: second differences remove a smooth
    motion and leave 6 sigma^2 of white noise; a jump (``controller.measured.impact``) is a mean
    of 2 POST_HALF_WIDTH + 1 samples minus a mean of PRE_SAMPLES, so its std is
    sigma sqrt(1 / PRE_SAMPLES + 1 / (2 POST_HALF_WIDTH + 1)); the variances are pooled over
    the trials."""
    variances = []
    for trial in diagnosis.trials:
        before = trial.dq_log[: trial.jump_samples[0] - PRE_SAMPLES + 1]
        if len(before) < 3:
            continue
        second = before[2:] - 2.0 * before[1:-1] + before[:-2]
        variances.append(np.mean(second**2, axis=0) / 6.0)
    sample_variance = np.mean(variances, axis=0) if variances else np.zeros(diagnosis.trials[0].dq_log.shape[1])
    return np.sqrt(sample_variance * (1.0 / PRE_SAMPLES + 1.0 / (2 * POST_HALF_WIDTH + 1)))


def near_zero_jumps(diagnosis: Diagnosis) -> np.ndarray:
    """Joints (bool, one per joint) whose measured jump is near zero: root mean square over the trials below
    ``NEAR_ZERO_STDS`` noise stds of a jump."""
    measured = np.array([t.jump for t in diagnosis.trials])
    return np.sqrt(np.mean(measured**2, axis=0)) < NEAR_ZERO_STDS * jump_noise_std(diagnosis)


def series(diagnosis: Diagnosis) -> dict[str, np.ndarray]:
    return {
        "measured": np.array([t.jump for t in diagnosis.trials]),
        "nominal sim": diagnosis.nominal_jumps,
        "extended sim": diagnosis.extended_jumps,
        **{m: p for m, p in diagnosis.predictions.items()},
    }


def absolute_errors(diagnosis: Diagnosis) -> dict[str, np.ndarray]:
    """|e| of eq. (25) (trials x joints) of both simulations and every predictor."""
    data = series(diagnosis)
    measured = data.pop("measured")
    return {name: np.abs(jumps - measured) for name, jumps in data.items()}


def save(fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=FIGURE_DPI, format="png")
    plt.close(fig)


def plot_jumps(diagnosis: Diagnosis, path: Path) -> None:
    postures = sorted({t.posture or "unknown" for t in diagnosis.trials})
    data = series(diagnosis)
    joints = np.arange(1, data["measured"].shape[1] + 1)
    fig, axes = plt.subplots(1, len(postures), figsize=(JUMPS_INCHES[0] * len(postures), JUMPS_INCHES[1]), squeeze=False, sharey=True)
    for ax, posture in zip(axes[0], postures):
        rows = [i for i, t in enumerate(diagnosis.trials) if (t.posture or "unknown") == posture]
        for k, name in enumerate(("measured", "nominal sim", "extended sim")):
            ax.bar(joints + (k - 1) * 0.27, data[name][rows].mean(axis=0), width=0.27, label=name)
        ax.set_title(f"{posture} ({len(rows)} trials)")
        ax.set_xlabel("joint")
        ax.set_ylabel("mean jump dq+ - dq- (rad/s)")
        ax.yaxis.set_tick_params(labelleft=True)
        ax.set_xticks(joints)
        ax.axhline(0.0, color="k", lw=0.5)
    axes[0][0].legend(fontsize=8)
    fig.suptitle("Joint-velocity jump per joint, mean over each posture's trials (all speeds pooled)")
    save(fig, path)


def plot_error_vs_speed(diagnosis: Diagnosis, path: Path) -> None:
    speeds = np.array([t.reference_speed for t in diagnosis.trials])
    levels = np.unique(speeds)
    fig, ax = plt.subplots(figsize=ERROR_VS_SPEED_INCHES)
    for name, errors in absolute_errors(diagnosis).items():
        average = errors.mean(axis=1)
        ax.plot(levels, [average[speeds == v].mean() for v in levels], "o-", label=name)
    ax.set_xlabel("reference normal speed (m/s)")
    ax.set_ylabel("average error, eq. (26) (rad/s)")
    ax.set_ylim(bottom=0.0)
    ax.set_title("Error against the measured jump, mean over the trials\nat each speed (postures pooled)", fontsize=10)
    ax.legend(fontsize=8)
    save(fig, path)


def plot_predictor_errors(diagnosis: Diagnosis, path: Path) -> None:
    errors = absolute_errors(diagnosis)
    joints = np.arange(1, next(iter(errors.values())).shape[1] + 1)
    fig, ax = plt.subplots(figsize=PREDICTOR_ERRORS_INCHES)
    width = 0.8 / len(errors)
    for k, (name, error) in enumerate(errors.items()):
        ax.bar(joints + (k - len(errors) / 2 + 0.5) * width, error.mean(axis=0), width, label=name)
    ax.set_xlabel("joint")
    ax.set_ylabel("mean |error|, eq. (25) (rad/s)")
    ax.set_xticks(joints)
    ax.set_title(
        f"Error against the measured jump per joint, mean over all {len(diagnosis.trials)} trials", fontsize=10
    )
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


def speed_section(diagnosis: Diagnosis, speeds: list[FeasibleSpeed]) -> list[str]:
    """The report's lines on the highest feasible contact speed and which answer to trust."""
    lines = [
        "",
        "## What it means for your robot: highest feasible contact speed (m/s)",
        "",
        "| posture | CRB closed form | nominal simulation | extended simulation |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {r.posture} | {r.crb_closed_form:.3f} | {r.nominal_plant:.3f} | {r.extended_plant:.3f} |" for r in speeds
    ]
    return lines + [""] + [r.sentence() for r in speeds] + ["", trusted_speed_text(diagnosis, speeds)]


def nominal_error_section(diagnosis: Diagnosis) -> list[str]:
    """The report's lines on what the nominal simulation gets wrong, joint by joint."""
    a = diagnosis.summary()["analysis"]
    lines = [
        "",
        "## What the nominal simulation gets wrong",
        "",
        "| joint | mean error (25) | mean abs error | sim / measured | share of error |",
        "|---|---|---|---|---|",
    ]
    near_zero = near_zero_jumps(diagnosis)
    for j in range(len(near_zero)):
        ratio = "-" if near_zero[j] else f"{a['per_joint_sim_to_measured_ratio'][j]:.3f}"
        lines.append(
            f"| {j + 1} | {a['per_joint_mean_error'][j]:+.4f} | {a['per_joint_mean_abs_error'][j]:.4f} | "
            f"{ratio} | {100 * a['per_joint_error_share'][j]:.1f} % |"
        )
    return lines + [
        "",
        f"Average error (26) grows by {a['error_vs_speed_slope']:.3f} (rad/s) per m/s of reference speed. "
        "A sim / measured ratio above 1 means the simulation overshoots that joint's jump; it is left out (-) "
        f"where the measured jump is near zero (root mean square below {NEAR_ZERO_STDS:g} noise stds of a jump).",
    ]


def fit_section(summary: dict) -> list[str]:
    """The report's table of the normalised residual of each signal block, nominal and final."""
    blocks = [b for b in BLOCKS if b in summary["fit"]]
    return [
        "## Fit against the noise (normalised residual: root mean square in noise units)",
        "",
        "| model | " + " | ".join(blocks) + " | fits the noise |",
        "|---|" + "---|" * (len(blocks) + 1),
        *(
            f"| {label} | " + " | ".join(f"{fit[b]:.2f}" for b in BLOCKS if b in fit) + f" | {boolean(fit['fits_noise'])} |"
            for label, fit in (("nominal", summary["nominal_fit"]), ("final", summary["fit"]))
        ),
    ]


def fitted_section(summary: dict) -> list[str]:
    """The report's fitted parameters and their 95 % intervals, only when causes are named."""
    if not summary["explained"]:
        return ["", "## Fitted parameters", "",
                "No cause is named, so no fitted value is a result (the best model found, which explains "
                "nothing, is the JSON's `best_model`)."]
    lines = ["", "## Fitted parameters and 95 % intervals", "",
             "| cause | parameter | value | 95 % interval |", "|---|---|---|---|"]
    for p in summary["parameter_intervals"]:
        lines.append(f"| {p['cause']} | {p['parameter']} | {number(p['value'])} | {interval_text(p['interval'])} |")
    intervals = {p["parameter"]: p["interval"] for p in summary["parameter_intervals"]}
    return lines + [f"\n{open_side_text(o, intervals[o['parameter']])}" for o in summary["open_sides"]]


def trial_section(summary: dict) -> list[str]:
    """The report's table of each trial's normalised residual under the final model, outliers marked."""
    outliers = set(summary["outlier_trials"])
    return ["", "## Trials (normalised residual of the final model, noise units)", "",
            "| trial | residual | stands out |", "|---|---|---|",
            *(f"| {r['id']} | {r['residual']:.2f} | {boolean(r['id'] in outliers)} |" for r in summary["trial_residuals"])]


def markdown(diagnosis: Diagnosis, speeds: list[FeasibleSpeed] | None = None) -> str:
    s = diagnosis.summary()
    lines = [
        "# Impact diagnosis",
        "",
        s["message"],
        "",
        f"- trials used: {s['trials']}, skipped: {len(s['skipped'])}",
        f"- causes: **{', '.join(s['causes']) or 'none'}** (explained: {boolean(s['explained'])}; "
        f"thresholds: every step "
        f"{100 * STEP_GAIN:.0f} % held-out gain, the causes together {100 * EXPLAINED_GAIN:.0f} % of the excess "
        "over the noise floor, and a model that fits the noise)",
        f"- parameters: {parameters_text(s['parameters'])}",
        f"- average error (26) of the held-out replays: nominal simulation {s['baseline_error']:.4f} rad/s, "
        f"extended simulation {s['extended_error']:.4f} rad/s, gain {100 * s['gain']:.1f} % "
        f"({100 * s['gain_over_floor']:.1f} % of the excess over the noise floor)",
        "",
        *fit_section(s),
        "",
        "## Selection steps",
        "",
        "Every path tried, the kept one first (add: a forward step; refine: the cause per joint; remove: a",
        "backward step, its gain is the cause's over the model without it).",
        "",
        "| step | path | action | cause | held-out residual (noise units) | gain | taken | selected |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k, step in enumerate(s["steps"], start=1):
        lines.append(
            f"| {k} | {step['path'] + 1} | {step['action']} | {step['cause']} | {step['heldout_error']:.4f} | "
            f"{100 * step['gain']:.1f} % | {boolean(step['accepted'])} | {boolean(step['selected'])} |"
        )
    lines += fitted_section(s)
    lines += trial_section(s)
    if speeds:
        lines += speed_section(diagnosis, speeds)
    lines += nominal_error_section(diagnosis)
    lines += [
        "",
        "## Candidate causes (cross-validated over trials)",
        "",
        "| cause | held-out residual (noise units) | gain | parameters |",
        "|---|---|---|---|",
    ]
    for c in sorted(s["candidates"], key=lambda c: -c["gain"]):
        lines.append(
            f"| {c['cause']} | {c['heldout_error']:.4f} | {100 * c['gain']:.1f} % | {parameters_text(c['parameters'])} |"
        )
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


def write_report(diagnosis: Diagnosis, out: str | Path, speeds: list[FeasibleSpeed] | None = None) -> Path:
    """Write ``report.md`` (with the feasible speeds when given) and the three figures into the
    directory ``out`` (created when missing), each file atomically; other files in ``out`` are
    left alone."""
    out = Path(out)
    for name, plot in (
        ("jumps.png", plot_jumps),
        ("error_vs_speed.png", plot_error_vs_speed),
        ("predictor_errors.png", plot_predictor_errors),
    ):
        write_atomic(out / name, lambda tmp, plot=plot: plot(diagnosis, tmp))
    return write_text_atomic(out / "report.md", markdown(diagnosis, speeds))
