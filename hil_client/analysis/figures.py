"""Figures of a lab log (PNG, matplotlib without a display).

matplotlib is imported on the first figure drawn, not with this module: ``hil-client``
imports it for every command, and matplotlib's import took a third of a second of
``hil-client --help`` and warned twice on stderr, before any one-line error, wherever the
home directory could not be written (a stranger's probe).
"""

from __future__ import annotations

import os
import sys
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hil_client.analysis.candidates import full_prediction
from hil_client.analysis.logio import LabLog, fill_gaps
from hil_client.analysis.phases import Phases
from rig_emulator import home_dir, private_temp_dir, writable_dir
from rig_emulator.atomic import replacing
from rig_emulator.model.water_heat import heat_to_water_kW

if TYPE_CHECKING:
    from types import ModuleType

    from hil_client.analysis.diagnose import Diagnosis

PHASE_LABELS = ("t0", "t1", "t2", "t3")


def _matplotlib_default_dirs() -> list[Path] | None:
    """The configuration and cache directories matplotlib uses when MPLCONFIGDIR is not set
    (its ``_get_config_or_cache_dir``), or None where they depend on a home directory that
    cannot be named."""
    home = home_dir()
    if not sys.platform.startswith(("linux", "freebsd")):
        return [home / ".matplotlib"] if home else None
    dirs = []
    for variable, under_home in (("XDG_CONFIG_HOME", ".config"), ("XDG_CACHE_HOME", ".cache")):
        base = os.environ.get(variable) or (str(home / under_home) if home else "")
        if not base:
            return None
        dirs.append(Path(base, "matplotlib"))
    return dirs


def _quiet_matplotlib_config_dir() -> None:
    """Point matplotlib at a private writable directory (MPLCONFIGDIR) where it could not
    write its own, as for numba's cache (:func:`rig_emulator.private_temp_dir`).

    Left alone, matplotlib warns twice on stderr and builds its font cache anew in a
    temporary directory on every run; an explicit MPLCONFIGDIR is respected (matplotlib
    ignores an empty one, and so does this)."""
    if os.environ.get("MPLCONFIGDIR"):
        return
    defaults = _matplotlib_default_dirs()
    if defaults and all(writable_dir(d) for d in defaults):
        return
    private = private_temp_dir("matplotlib")
    if private is not None:
        os.environ["MPLCONFIGDIR"] = str(private)


@cache
def _pyplot() -> ModuleType:
    """matplotlib's pyplot on the Agg backend (no display), imported once, on the first
    figure drawn."""
    _quiet_matplotlib_config_dir()
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def mark_phases(ax, phases: Phases) -> None:
    """Vertical lines and labels at t0..t3 (time axis in hours)."""
    for label, x in zip(PHASE_LABELS, (phases.t0, phases.t1, phases.t2, phases.t3), strict=True):
        ax.axvline(x / 3600.0, color="0.6", lw=0.8, ls="--")
        ax.text(
            x / 3600.0,
            1.0,
            label,
            transform=ax.get_xaxis_transform(),
            ha="center",
            va="bottom",
            fontsize=8,
            color="0.4",
        )


def _save(fig, path: Path, dpi: int = 110) -> Path:
    """Lay out, write and close a figure."""
    fig.tight_layout()
    try:
        with replacing(path) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        _pyplot().close(fig)
    return path


def energy_and_temperatures(log: LabLog, phases: Phases, path: Path, title: str) -> Path:
    """Energy flows and temperatures over time, like Fig. 7 of Carlon et al. (2015)."""
    t = log.t
    h = t / 3600.0
    f = {
        n: fill_gaps(log[n], t)
        for n in (
            "water_flow_kg_h",
            "water_in_temp_C",
            "water_out_temp_C",
            "boiler_water_temp_C",
            "flue_gas_temp_C",
            "balance_mass_kg",
            "room_temp_C",
        )
    }
    q_water = heat_to_water_kW(f["water_flow_kg_h"], f["water_in_temp_C"], f["water_out_temp_C"])
    window = max(int(60 / max(np.median(np.diff(t)), 1e-9)), 1)
    smooth = np.convolve(q_water, np.ones(window) / window, mode="same")
    fig, axes = _pyplot().subplots(
        3, 1, figsize=(11, 8.5), sharex=True, gridspec_kw={"height_ratios": [1.2, 1.2, 0.8]}
    )
    ax = axes[0]
    ax.plot(h, q_water, color="tab:blue", lw=0.4, alpha=0.35)
    ax.plot(h, smooth, color="tab:blue", lw=1.2, label="heat to water (Eq. 7), 1-min mean")
    ax.axhline(0, color="0.3", lw=0.5)
    ax.set_ylabel("power [kW]")
    ax.legend(loc="upper right", fontsize=8)
    mark_phases(ax, phases)
    ax = axes[1]
    for name, color, label in (
        ("boiler_water_temp_C", "tab:red", "water inside the boiler"),
        ("water_out_temp_C", "tab:orange", "forward (exit pipe)"),
        ("water_in_temp_C", "tab:green", "return"),
        ("room_temp_C", "0.5", "room"),
    ):
        ax.plot(h, f[name], color=color, lw=1.0, label=label)
    ax.set_ylabel("temperature [C]")
    twin = ax.twinx()
    twin.plot(h, f["flue_gas_temp_C"], color="tab:purple", lw=0.8, label="flue gas")
    twin.set_ylabel("flue gas [C]", color="tab:purple")
    lines = ax.get_lines() + twin.get_lines()
    ax.legend(lines, [ln.get_label() for ln in lines], loc="upper right", fontsize=8)
    mark_phases(ax, phases)
    ax = axes[2]
    ax.plot(h, f["balance_mass_kg"], color="tab:brown", lw=1.0, label="balance")
    ax.set_ylabel("balance [kg]")
    if log.has("boiler_on"):
        twin = ax.twinx()
        twin.fill_between(
            h,
            0,
            np.nan_to_num(log["boiler_on"]),
            step="post",
            color="tab:red",
            alpha=0.15,
            label="burner firing",
        )
        twin.set_yticks([0, 1])
        twin.set_ylabel("firing")
    ax.set_xlabel("time [h]")
    mark_phases(ax, phases)
    fig.suptitle(title)
    path.parent.mkdir(parents=True, exist_ok=True)
    return _save(fig, path)


def _fit_figure(
    path: Path,
    x,
    y,
    *,
    color: str,
    x_max: float,
    a: float,
    b: float,
    fit_label: str,
    xlabel: str,
    ylabel: str,
    title: str,
) -> Path:
    """Stationary-interval points and the fitted line a + b x from 0 to x_max."""
    fig, ax = _pyplot().subplots(figsize=(6, 4.2))
    ax.plot(x, y, "o", color=color, label="stationary intervals")
    xs = np.linspace(0, x_max, 10)
    ax.plot(xs, a + b * xs, "k-", label=fit_label)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(fontsize=8)
    return _save(fig, path)


def calibration_figures(cal, stem: Path) -> list[Path]:
    """Fig. 4 (flue-gas delta-T regression) and Fig. 5 (lambda against dry fuel flow)."""
    p = cal.params
    x, y = cal.fig4["x"], cal.fig4["y"]
    f, lam = cal.fig5["fuel"], cal.fig5["lambda"]
    return [
        _fit_figure(
            stem.with_name(stem.name + "_fig4_flue_gas.png"),
            x,
            y,
            color="tab:red",
            x_max=max(1.0, float(np.max(x)) if len(x) else 1.0),
            a=p.dt_nom_K,
            b=p.dt_hx_wat_K,
            fit_label=f"dTnom {p.dt_nom_K:.2f} K, dThx,wat {p.dt_hx_wat_K:.2f} K",
            xlabel="1 - m_w / m_w,nom [-]",
            ylabel="T_fg - T_w,in [K]",
            title="Flue-gas temperature (Eq. 8, cf. Fig. 4)",
        ),
        _fit_figure(
            stem.with_name(stem.name + "_fig5_lambda.png"),
            f,
            lam,
            color="tab:blue",
            x_max=max(float(np.max(f)) * 1.1 if len(f) else 3.0, 0.5),
            a=p.fac_a_lambda,
            b=p.fac_b_lambda_h_kg,
            fit_label=f"facA {p.fac_a_lambda:.2f}, facB {p.fac_b_lambda_h_kg:.2f} h/kg",
            xlabel="dry fuel flow [kg/h]",
            ylabel="lambda (from O2) [-]",
            title="Excess air (Eq. 9, cf. Fig. 5)",
        ),
    ]


def validation_figures(comp, phases: Phases, stem: Path, title: str) -> list[Path]:
    """Model against lab over time (cf. Figs. 6, 7) and as scatter with the identity line and
    a +-10 % band (cf. Figs. 8, 9)."""
    h = comp.t / 3600.0
    fig, axes = _pyplot().subplots(3, 1, figsize=(11, 8.5), sharex=True)
    labels = (
        ("boiler_water_temp_C", "water inside the boiler [C]"),
        ("heat_to_water_kW", "heat to water [kW]"),
        ("flue_gas_loss_kW", "flue-gas loss [kW]"),
    )
    for ax, (name, label) in zip(axes, labels, strict=True):
        ax.plot(h, comp.lab[name], color="tab:red", lw=0.7, label="lab")
        ax.plot(h, comp.model[name], color="k", lw=0.9, ls="--", label="model")
        ax.set_ylabel(label)
        mark_phases(ax, phases)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time [h]")
    fig.suptitle(title)
    paths = [_save(fig, stem.with_name(stem.name + "_timeseries.png"))]
    fig, axes = _pyplot().subplots(1, 2, figsize=(10, 4.6))
    mask = comp.segments["start_up"] | comp.segments["test"]
    for ax, (name, label) in zip(axes, labels[:2], strict=True):
        lab, model = comp.lab[name][mask], comp.model[name][mask]
        ok = np.isfinite(lab) & np.isfinite(model)  # a signal with no readings: no points
        lab, model = lab[ok], model[ok]
        ax.plot(lab, model, ".", ms=1.5, alpha=0.4, color="tab:blue")
        lo, hi = (
            (float(min(lab.min(), model.min())), float(max(lab.max(), model.max())))
            if ok.any()
            else (0.0, 1.0)
        )
        xs = np.linspace(lo, hi, 10)
        ax.plot(xs, xs, "k-", lw=1, label="identity")
        ax.fill_between(xs, 0.9 * xs, 1.1 * xs, color="0.8", alpha=0.5, label="+-10 %")
        ax.set_xlabel(f"lab: {label}")
        ax.set_ylabel(f"model: {label}")
        ax.legend(fontsize=8)
    fig.suptitle(title + " (t0..t2)")
    paths.append(_save(fig, stem.with_name(stem.name + "_scatter.png")))
    return paths


def diagnosis_figures(result: Diagnosis, out_dir: Path) -> list[Path]:
    """Residuals by phase (validation log, unaugmented model) and before/after overlays of
    the signal where the gap lies."""
    from hil_client.analysis.replay import SIGNALS

    val = result.validation
    base = val.base_prediction()
    fig, axes = _pyplot().subplots(len(SIGNALS), 1, figsize=(11, 10), sharex=True)
    h = val.t / 3600.0
    for ax, s in zip(axes, SIGNALS, strict=True):
        ax.plot(h, val.lab[s] - base[s], color="tab:red", lw=0.6)
        ax.axhline(0, color="0.3", lw=0.5)
        ax.set_ylabel(f"lab - model\n{s}", fontsize=8)
        mark_phases(ax, val.phases)
    axes[-1].set_xlabel("time [h]")
    fig.suptitle("Residuals of the calibrated one-node model on the validation log")
    paths = [_save(fig, out_dir / "residuals_by_phase.png", dpi=100)]
    shrink = result.shrinkage
    effect = result.effect
    if shrink is not None:
        s = shrink["signal"]
        params = next(c["params"] for c in result.candidates if c["effect"] == effect)
        after = full_prediction(val, effect, params)
        fig, ax = _pyplot().subplots(figsize=(11, 4.5))
        ax.plot(h, val.lab[s], color="tab:red", lw=0.8, label="lab")
        ax.plot(h, base[s], color="k", lw=0.9, ls="--", label="model")
        ax.plot(h, after[s], color="tab:blue", lw=0.9, label=f"model + {effect}")
        ax.set_ylabel(s)
        ax.set_xlabel("time [h]")
        mark_phases(ax, val.phases)
        ax.legend(fontsize=8)
        pct = shrink["shrink_pct"]
        ax.set_title(
            f"validation log, {s}: RMSD where the effect acts ({shrink['phase']}) "
            f"{_num(shrink['validation_rmsd_before'])} -> "
            f"{_num(shrink['validation_rmsd_after'])} "
            + (f"({pct:.0f} % less)" if pct is not None else "(not measurable)")
        )
        paths.append(_save(fig, out_dir / "before_after.png", dpi=100))
    return paths


def _num(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def benchmark_figure(scores: dict, path: Path) -> Path:
    """The gap benchmark at a glance: the confusion matrix and the confidence's
    reliability (share right per confidence bin, against the diagonal)."""
    answers = list(scores["confusion"])
    found = [*answers, "error"]
    matrix = np.array([[scores["confusion"][t][f] for f in found] for t in answers])
    fig, (ax1, ax2) = _pyplot().subplots(
        1, 2, figsize=(12, 4.8), gridspec_kw={"width_ratios": [3, 2]}
    )
    ax1.imshow(matrix, cmap="Blues")
    for i in range(len(answers)):
        for j in range(len(found)):
            if matrix[i, j]:
                ax1.text(j, i, str(matrix[i, j]), ha="center", va="center", fontsize=9)
    ax1.set_xticks(range(len(found)), [f.replace("_", "\n") for f in found], fontsize=7)
    ax1.set_yticks(range(len(answers)), answers, fontsize=8)
    ax1.set_xlabel("found")
    ax1.set_ylabel("truth")
    ax1.set_title(f"{scores['reality']}: accuracy {scores['accuracy']:.0%} on {scores['cases']}")
    bins = [r for r in scores["reliability"] if r["answers"]]
    mids = [(r["confidence_from"] + r["confidence_to"]) / 2 for r in bins]
    ax2.plot([0, 1], [0, 1], color="0.6", lw=0.8, ls="--", label="perfectly calibrated")
    ax2.bar(
        mids,
        [r["share_right"] for r in bins],
        width=[r["confidence_to"] - r["confidence_from"] for r in bins],
        alpha=0.6,
        edgecolor="k",
        label="share right",
    )
    for m, r in zip(mids, bins, strict=True):
        ax2.text(m, 0.03, f"n={r['answers']}", ha="center", fontsize=8)
    ax2.set_xlim(0, 1)
    ax2.set_ylim(0, 1.05)
    ax2.set_xlabel("confidence")
    ax2.set_ylabel("share of answers right")
    ax2.set_title("reliability of the confidence")
    ax2.legend(fontsize=8, loc="upper left")
    return _save(fig, path, dpi=100)
