"""summary.png: a sweep in one picture.

One row per swept key (or one row for all runs when only seeds vary); in each row, per
value of that key: the share of runs that succeeded, missed the goal or failed (stacked
bars, with counts), then the distribution of each varying metric (box plot with every run
as a dot). Drawn on the Agg canvas directly, like the runs' report pictures.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from orchestrator.sweep.results import FAILED

PREFERRED = ("time_to_goal", "path_length", "min_clearance", "collisions", "recoveries")
MAX_METRICS = 5
OUTCOMES = (("success", "#2ca02c"), ("goal_not_met", "#ff7f0e"), ("failed", "#d62728"))
DPI = 100


def write_summary_png(rows: list[dict[str, Any]], keys: list[str], metrics: list[str],
                      path: Path, title: str) -> Path:
    """Draw the rows of a sweep's table into ``path``; return it."""
    swept = [k for k in keys if len({_label(r[k]) for r in rows}) > 1] or [None]
    shown = chosen_metrics(rows, metrics)
    cols = 1 + len(shown)
    fig = Figure(figsize=(3.6 * cols, 3.0 * len(swept) + 0.8), dpi=DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(len(swept), cols, squeeze=False)
    for row_axes, key in zip(axes, swept, strict=True):
        groups = _groups(rows, key)
        _outcomes(row_axes[0], groups, key)
        for ax, metric in zip(row_axes[1:], shown, strict=True):
            _distribution(ax, groups, metric, key)
    ok = sum(1 for r in rows if r["success"])
    fig.suptitle(f"{title}: {len(rows)} runs, {ok} succeeded "
                 f"({100 * ok / max(len(rows), 1):.0f} %)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    return path


def chosen_metrics(rows: list[dict[str, Any]], metrics: list[str]) -> list[str]:
    """The metrics worth a panel: those that vary across runs, preferred ones first."""
    varying = [m for m in metrics
               if len({r.get(m) for r in rows if _number(r.get(m)) is not None}) > 1]
    order = sorted(varying, key=lambda m: (PREFERRED.index(m) if m in PREFERRED
                                           else len(PREFERRED), m))
    return order[:MAX_METRICS]


def _groups(rows: list[dict[str, Any]], key: str | None) -> dict[str, list[dict[str, Any]]]:
    """Rows by the value of ``key`` (all in one group when None), values in first-seen order."""
    groups: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        groups.setdefault("all runs" if key is None else _label(row[key]), []).append(row)
    return groups


def _outcomes(ax, groups: dict[str, list[dict[str, Any]]], key: str | None) -> None:
    """Stacked bars: the share of runs per outcome for each value, 'k/n' succeeded above."""
    x = np.arange(len(groups))
    bottom = np.zeros(len(groups))
    for outcome, colour in OUTCOMES:
        share = np.array([sum(1 for r in g if _outcome(r) == outcome) / len(g)
                          for g in groups.values()])
        ax.bar(x, share, bottom=bottom, color=colour, label=outcome.replace("_", " "))
        bottom += share
    for i, group in enumerate(groups.values()):
        ok = sum(1 for r in group if r["success"])
        ax.text(i, 1.02, f"{ok}/{len(group)}", ha="center", va="bottom", fontsize=8)
    ax.set_ylim(0, 1.15)
    ax.set_ylabel("share of runs")
    ax.set_title("success rate", fontsize=10)
    _x_axis(ax, list(groups), key)
    ax.legend(fontsize=7, loc="lower right")


def _distribution(ax, groups: dict[str, list[dict[str, Any]]], metric: str,
                  key: str | None) -> None:
    """A box plot of ``metric`` per value, every run a dot (deterministic jitter)."""
    data = [[v for v in (_number(r.get(metric)) for r in g) if v is not None]
            for g in groups.values()]
    positions = [i for i, d in enumerate(data) if d]
    if positions:
        ax.boxplot([data[i] for i in positions], positions=positions, widths=0.5,
                   showfliers=False)
    jitter = np.random.default_rng(0)
    for i, values in enumerate(data):
        ax.scatter(i + jitter.uniform(-0.15, 0.15, len(values)), values, s=8, alpha=0.6,
                   color="#1f77b4", zorder=3)
    ax.set_title(metric, fontsize=10)
    _x_axis(ax, list(groups), key)


def _x_axis(ax, labels: list[str], key: str | None) -> None:
    ax.set_xticks(range(len(labels)), labels, fontsize=8,
                  rotation=30 if max(map(len, labels)) > 6 else 0)
    ax.set_xlim(-0.6, len(labels) - 0.4)
    ax.set_xlabel(key.rsplit(".", 1)[-1] if key else "", fontsize=9)


def _outcome(row: dict[str, Any]) -> str:
    if row["status"] in FAILED:
        return "failed"
    return "success" if row["success"] else "goal_not_met"


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return None if math.isnan(value) else float(value)


def _label(value: Any) -> str:
    return value if isinstance(value, str) else str(value)
