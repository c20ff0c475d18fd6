"""Time against error: the arithmetic of the benchmark (``python -m vpl_addon bench``), no Blender.

A *curve* is one method's runs on one scene: wall seconds and an error (rMAE) per budget. Curves are read the way
Li et al. read their convergence plots (Virtual Blue Noise Lighting, Fig. 18): on log-log axes, where both Monte
Carlo noise (error ~ time^-1/2) and most biased methods are close to straight lines, so values between two runs are
interpolated linearly in (log t, log error). Nothing is extrapolated silently: a time outside a curve's runs gives
``None`` with the reason, and the one extrapolation the benchmark allows (Cycles' time to reach an error below its
best run, by the 1/sqrt(spp) law of an unbiased path tracer whose time grows with spp) is labelled as such.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Curve:
    seconds: np.ndarray  # wall seconds of each run, in budget order
    error: np.ndarray  # rMAE of each run
    budget: np.ndarray  # the method's budget knob of each run

    @staticmethod
    def of(seconds, error, budget=None) -> "Curve":
        """Runs in budget order; runs of one budget (repeated with other seeds) become one point, their mean wall
        time and mean rMAE (on veach-ajar one draw's rMAE varies by 10-30 % from seed to seed: ir at 65536 VPLs
        in ``python -m vpl_addon bench --seeds 4``)."""
        seconds = np.asarray(seconds, np.float64)
        error = np.asarray(error, np.float64)
        budget = np.arange(len(seconds)) if budget is None else np.asarray(budget)
        budgets, group = np.unique(budget, return_inverse=True)
        count = np.bincount(group, minlength=len(budgets))

        def mean(values):
            return np.bincount(group, values, len(budgets)) / count
        return Curve(mean(seconds), mean(error), budgets)

    def __len__(self):
        return len(self.seconds)


@dataclass
class Reading:
    """A value read off a curve, or None with the reason it cannot be read honestly."""
    value: float | None
    note: str = ""

    def __str__(self):
        return self.note if self.value is None else f"{self.value:.4g}" + (f" ({self.note})" if self.note else "")


def error_at(curve: Curve, seconds: float) -> Reading:
    """rMAE of the curve at a wall time, interpolated log-log between the two runs around it."""
    if len(curve) == 0:
        return Reading(None, "n/a (no runs)")
    order = np.argsort(curve.seconds, kind="stable")
    t, e = curve.seconds[order], curve.error[order]
    if seconds < t[0]:
        return Reading(None, f"n/a (fastest run took {t[0]:.2f} s)")
    if seconds > t[-1]:
        return Reading(None, f"n/a (slowest run took {t[-1]:.2f} s)")
    if np.any(e <= 0):
        return Reading(float(np.interp(seconds, t, e)))
    return Reading(float(np.exp(np.interp(math.log(seconds), np.log(t), np.log(e)))))


def time_to_error(curve: Curve, target: float, extrapolate: bool = True) -> Reading:
    """Wall seconds the curve needs to bring its rMAE down to ``target``.

    Follows the runs in budget order and interpolates log-log inside the first run pair that crosses the target.
    If the first run is already below it, the answer is that run's time, noted as an upper bound. If no run gets
    there, the last run is extended by the Monte Carlo law error ~ spp^-1/2, time ~ spp, i.e. t = t_last *
    (e_last / target)^2, and noted "extrapolated" (only meaningful for an unbiased method such as Cycles)."""
    if len(curve) == 0 or not target > 0:
        return Reading(None, "n/a (no runs)" if len(curve) == 0 else "n/a (no target)")
    t, e = curve.seconds, curve.error
    if e[0] <= target:
        return Reading(float(t[0]), f"at most: its first run, {curve.budget[0]}, is already there")
    for i in range(len(t) - 1):
        if e[i] > target >= e[i + 1]:
            x = (math.log(target) - math.log(e[i])) / (math.log(e[i + 1]) - math.log(e[i]))
            return Reading(float(math.exp(math.log(t[i]) + x * (math.log(t[i + 1]) - math.log(t[i])))))
    if not extrapolate:
        return Reading(None, f"n/a (best run reaches {e.min():.4g})")
    best = int(np.argmin(e))
    return Reading(float(t[best] * (e[best] / target) ** 2),
                   f"extrapolated from {curve.budget[best]} by error ~ 1/sqrt(spp)")


def fit_exponent(x, y) -> float:
    """Least-squares slope of log y against log x: y ~ x^k gives k."""
    lx, ly = np.log(np.asarray(x, np.float64)), np.log(np.asarray(y, np.float64))
    if len(lx) < 2 or np.ptp(lx) == 0:
        return float("nan")
    return float(np.polyfit(lx, ly, 1)[0])


@dataclass
class EqualTime:
    seconds: float
    best: str | None  # the competing method with the lowest error at that time
    best_error: Reading
    cycles_error: Reading

    @property
    def ratio(self) -> float | None:
        """Cycles' error over the best method's error at equal time (> 1: the method wins)."""
        if self.best_error.value is None or self.cycles_error.value is None or self.best_error.value <= 0:
            return None
        return self.cycles_error.value / self.best_error.value


def best_at(curves: dict[str, Curve], seconds: float) -> tuple[str | None, Reading]:
    """The curve with the lowest interpolated error at ``seconds`` (among those that reach that time)."""
    readings = {name: error_at(c, seconds) for name, c in curves.items()}
    known = {n: r for n, r in readings.items() if r.value is not None}
    if not known:
        notes = "; ".join(f"{n} {r.note}" for n, r in readings.items())
        return None, Reading(None, notes or "n/a (no method)")
    name = min(known, key=lambda n: known[n].value)
    return name, known[name]


def equal_time(curves: dict[str, Curve], cycles: Curve, seconds: float) -> EqualTime:
    best, reading = best_at(curves, seconds)
    return EqualTime(seconds, best, reading, error_at(cycles, seconds))


@dataclass
class EqualError:
    seconds: float  # the methods' time whose error Cycles must reach
    best: str | None
    target: Reading  # the best method's error at that time
    cycles_time: Reading  # Cycles' time to reach it

    @property
    def speedup(self) -> float | None:
        """Cycles' time to the best method's error over the method's time (> 1: the method is faster)."""
        if self.target.value is None or self.cycles_time.value is None:
            return None
        return self.cycles_time.value / self.seconds


def equal_error(curves: dict[str, Curve], cycles: Curve, seconds: float = 10.0) -> EqualError:
    best, target = best_at(curves, seconds)
    if target.value is None:
        return EqualError(seconds, None, target, Reading(None, "n/a (no method reaches that time)"))
    return EqualError(seconds, best, target, time_to_error(cycles, target.value))


def format_ratio(value: float | None, note: str = "") -> str:
    if value is None:
        return note or "n/a"
    return f"{value:.2f}x" + (f" ({note})" if note else "")


def plot(path: str, title: str, panels: dict[str, dict[str, Curve]]) -> None:
    """Log-log rMAE against wall seconds, one panel per compared pass, one line per method (a mark per budget,
    the smallest and largest budget written next to their marks)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 3.8), dpi=80, squeeze=False)
    for ax, (pass_name, curves) in zip(axes[0], panels.items()):
        for name, c in curves.items():
            if len(c) == 0:
                continue
            style = "--" if name.startswith("cycles") else "-"
            line, = ax.loglog(c.seconds, c.error, style, marker="o", markersize=3.5, label=name)
            for i in {0, len(c) - 1}:
                ax.annotate(str(c.budget[i]), (c.seconds[i], c.error[i]), fontsize=6, color=line.get_color(),
                            xytext=(3, 3), textcoords="offset points")
        for t in (2.0, 10.0):
            ax.axvline(t, color="0.8", linewidth=0.8, zorder=0)
        ax.set_xlabel("wall seconds")
        ax.set_ylabel("rMAE")
        ax.set_title(pass_name, fontsize=9)
        ax.grid(True, which="both", linewidth=0.3, alpha=0.5)
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
