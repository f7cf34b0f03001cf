"""Figures of ``rovis eval``, after the paper's Figs. 6–8, drawn from a ``results.json``
document (:meth:`rovis.evaluate.Evaluation.to_dict`).

matplotlib (the ``plot`` extra) is imported only here, when a figure is drawn, and always
through the Agg canvas: no display, no pyplot state.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rovis.io import write_figure_atomic

FIGURES = ("positions.png", "yaw.png", "lux.png")


def _mpl() -> tuple[Any, Any]:
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise ImportError("the eval plots need matplotlib: pip install 'rovis[plot]' "
                          "(or use --no-plots)") from exc
    return Figure, FigureCanvasAgg


def _save(fig: Any, path: Path) -> Path:
    return write_figure_atomic(fig, path)


def _grid(n: int) -> tuple[int, int]:
    cols = min(n, 3)
    return (n + cols - 1) // cols, cols


def _pairs(doc: Mapping[str, Any], method: str) -> list[tuple[dict[str, Any], dict[str, Any], dict[str, Any]]]:
    """(scene, true book, match) for every matched book of ``method``."""
    out = []
    for scene in doc["scenes"]:
        score = scene["methods"].get(method)
        if score is None:
            continue
        for m in score["matches"]:
            out.append((scene, scene["books"][m["truth"]], m))
    return out


def plot_positions(doc: Mapping[str, Any], path: str | os.PathLike[str]) -> Path:
    """Fig. 6: reconstructed vs true book centres on the desk (x–y), one panel per method;
    missed books ringed in red."""
    Figure, Canvas = _mpl()
    methods = doc["methods"]
    rows, cols = _grid(len(methods))
    fig = Figure(figsize=(4.2 * cols, 3.6 * rows), dpi=100, layout="constrained")
    Canvas(fig)
    for k, method in enumerate(methods):
        ax = fig.add_subplot(rows, cols, k + 1)
        true = np.array([b["center"][:2] for s in doc["scenes"] for b in s["books"]]).reshape(-1, 2)
        missed = np.array([b["center"][:2] for s in doc["scenes"] if method in s["methods"]
                           for b, j in zip(s["books"], s["methods"][method]["found"])
                           if j is None]).reshape(-1, 2)
        pairs = _pairs(doc, method)
        ax.scatter(true[:, 0], true[:, 1], s=14, facecolors="none", edgecolors="0.3", lw=0.8,
                   label="true")
        if len(missed):
            ax.scatter(missed[:, 0], missed[:, 1], s=40, facecolors="none", edgecolors="C3",
                       lw=1.0, label="missed")
        if pairs:
            t = np.array([b["center"][:2] for _, b, _ in pairs])
            e = np.array([m["center"][:2] for _, _, m in pairs])
            for a, b in zip(t, e):
                ax.plot([a[0], b[0]], [a[1], b[1]], color="C0", lw=0.6)
            ax.scatter(e[:, 0], e[:, 1], s=12, marker="x", color="C0", lw=0.9,
                       label="reconstructed")
        ax.set_title(f"{method}: {len(pairs)} of {len(true)} found", fontsize=10)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(True, lw=0.3)
        if k == 0:
            ax.legend(fontsize=7, loc="best")
    fig.suptitle("Book centres O, world frame (cf. the paper's Fig. 6)")
    return _save(fig, Path(path))


def plot_yaw(doc: Mapping[str, Any], path: str | os.PathLike[str]) -> Path:
    """Fig. 7: estimated vs true yaw of the long axis over 0–360°, one panel per method (the
    estimate unwrapped to the true value's branch: the 180°/90° symmetry is no error)."""
    Figure, Canvas = _mpl()
    methods = doc["methods"]
    rows, cols = _grid(len(methods))
    fig = Figure(figsize=(4.0 * cols, 3.6 * rows), dpi=100, layout="constrained")
    Canvas(fig)
    for k, method in enumerate(methods):
        ax = fig.add_subplot(rows, cols, k + 1)
        pairs = _pairs(doc, method)
        ax.plot([0, 360], [0, 360], color="0.6", lw=0.8, ls="--")
        if pairs:
            t = np.array([b["yaw_deg"] for _, b, _ in pairs])
            e = t + np.array([m["errors"]["psi_deg"] for _, _, m in pairs])
            ax.scatter(t, e, s=10, color="C1")
        ax.set_xlim(0, 360)
        ax.set_ylim(-20, 380)
        ax.set_xticks(range(0, 361, 90))
        ax.set_yticks(range(0, 361, 90))
        ax.set_title(f"{method} ({len(pairs)} books)", fontsize=10)
        ax.set_xlabel("true Ψ [°]")
        ax.set_ylabel("estimated Ψ [°]")
        ax.grid(True, lw=0.3)
    fig.suptitle("Yaw of the long axis (cf. the paper's Fig. 7)")
    return _save(fig, Path(path))


def _lux_groups(lux: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Group centres and each scene's group: the distinct levels when there are few (the
    ``table2`` sweep), else 10 logarithmic bins."""
    lux_a = np.asarray(lux, np.float64)
    levels = np.unique(np.round(lux_a, 1))
    if len(levels) <= 16:
        return levels, np.searchsorted(levels, np.round(lux_a, 1))
    edges = np.geomspace(lux_a.min(), lux_a.max() * (1 + 1e-9), 11)
    idx = np.clip(np.searchsorted(edges, lux_a, side="right") - 1, 0, 9)
    return np.sqrt(edges[:-1] * edges[1:]), idx


def plot_lux(doc: Mapping[str, Any], path: str | os.PathLike[str]) -> Path:
    """Fig. 8: per method, the mean position error |O_e| and |Ψ_e| of the matched books and the
    recall, against the light level."""
    Figure, Canvas = _mpl()
    scenes = [s for s in doc["scenes"] if s.get("lux") is not None]
    fig = Figure(figsize=(13.5, 3.9), dpi=100, layout="constrained")
    Canvas(fig)
    axes = [fig.add_subplot(1, 3, k + 1) for k in range(3)]
    if scenes:
        centres, group = _lux_groups([s["lux"] for s in scenes])
        for c, method in enumerate(doc["methods"]):
            pos: list[list[float]] = [[] for _ in centres]
            yaw: list[list[float]] = [[] for _ in centres]
            books = np.zeros(len(centres))
            found = np.zeros(len(centres))
            for s, g in zip(scenes, group):
                score = s["methods"].get(method)
                if score is None:
                    continue
                books[g] += len(s["books"])
                found[g] += sum(j is not None for j in score["found"])
                for m in score["matches"]:
                    e = m["errors"]
                    pos[g].append(float(np.linalg.norm([e["x"], e["y"], e["z"]])))
                    yaw[g].append(abs(e["psi_deg"]))
            style = dict(marker="o", ms=3.5, lw=1.2, color=f"C{c % 10}", label=method)
            mean_pos = [np.mean(v) if v else np.nan for v in pos]
            mean_yaw = [np.mean(v) if v else np.nan for v in yaw]
            recall = np.where(books > 0, found / np.maximum(books, 1), np.nan)
            axes[0].plot(centres, mean_pos, **style)
            axes[1].plot(centres, mean_yaw, **style)
            axes[2].plot(centres, recall, **style)
    titles = ("mean position error |O_e| [m]", "mean yaw error |Ψ_e| [°]", "recall")
    for ax, title in zip(axes, titles):
        ax.set_xscale("log")
        ax.set_xlabel("illuminance [lx]")
        ax.set_title(title, fontsize=10)
        ax.grid(True, which="both", lw=0.3)
    axes[0].axhline(0.01, color="0.5", lw=0.8, ls=":")  # the 1 cm grasp tolerance
    axes[0].set_ylim(bottom=0.0)
    axes[1].set_ylim(bottom=0.0)
    axes[2].set_ylim(-0.03, 1.03)
    if scenes:
        axes[2].legend(fontsize=7, loc="best")
    fig.suptitle("Error and recall against light (cf. the paper's Fig. 8)")
    return _save(fig, Path(path))


def write_plots(doc: Mapping[str, Any], out: str | os.PathLike[str]) -> list[Path]:
    """All three figures into ``out``: ``positions.png``, ``yaw.png``, ``lux.png``."""
    out = Path(out)
    return [plot_positions(doc, out / FIGURES[0]), plot_yaw(doc, out / FIGURES[1]),
            plot_lux(doc, out / FIGURES[2])]
