"""PNG pictures of the ensemble products (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from fem_runout.output.hazard import GridTarget

__all__ = ["draw_histograms", "draw_products", "histogram_range"]

_HISTOGRAMS = (("runout_length", "run-out [m]", 1.0), ("travel_angle_deg", "travel angle [°]", 1.0),
               ("affected_area", "affected area [ha]", 1e-4),
               ("deposit_volume", "deposit volume [m³]", 1.0))


def _crop(maps: dict[str, np.ndarray], target: GridTarget, margin: int = 10
          ) -> tuple[tuple[slice, slice], tuple[float, float, float, float]]:
    """Rows/columns around every pixel any map has a positive value in, and their extent."""
    any_data = np.zeros(target.shape, dtype=bool)
    for values in maps.values():
        any_data |= np.nan_to_num(values) > 0
    rows, cols = np.nonzero(any_data) if any_data.any() else np.indices(target.shape)
    r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, target.shape[0])
    c0, c1 = max(cols.min() - margin, 0), min(cols.max() + margin + 1, target.shape[1])
    t = target.transform
    extent = (t.c + t.a * c0, t.c + t.a * c1, t.f + t.e * r1, t.f + t.e * r0)
    return (slice(r0, r1), slice(c0, c1)), extent


def _panels(maps: dict[str, np.ndarray], names: list[str], target: GridTarget, path: Path,
            label: str, vmax: float | None) -> None:
    import matplotlib.pyplot as plt

    window, extent = _crop({k: maps[k] for k in names}, target)
    fig, axes = plt.subplots(1, len(names), figsize=(3.4 * len(names), 4.6), sharey=True,
                             squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        values = maps[name][window]
        shown = np.where(np.nan_to_num(values) > 0, values, np.nan)
        im = ax.imshow(shown, extent=extent, cmap="viridis", vmin=0, vmax=vmax)
        ax.set_title(name.replace("probability_", "P ").replace("_ge_", " ≥ "), fontsize=9)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    fig.colorbar(im, ax=axes, shrink=0.8, label=label)
    fig.savefig(path, dpi=90, bbox_inches="tight")
    plt.close(fig)


def draw_histograms(records: list[dict[str, Any]], path: Path) -> None:
    """Draw the members' run-out, travel angle, area and deposit histograms to ``path``."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(_HISTOGRAMS), figsize=(3.3 * len(_HISTOGRAMS), 3))
    for ax, (key, label, scale) in zip(axes, _HISTOGRAMS, strict=True):
        values = np.array([r["summary"][key] for r in records], dtype=float) * scale
        ax.hist(values, bins=max(5, int(np.sqrt(len(values)))), range=histogram_range(values),
                color="tab:blue")
        ax.set_xlabel(label)
    axes[0].set_ylabel("members")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def histogram_range(values: np.ndarray) -> tuple[float, float] | None:
    """Return the histogram's range: the data's, widened where members agree to round-off.

    numpy cannot cut 5 bins out of a range of a few ulps (members equal but for the last
    bits, e.g. a run-out of 64 m summed in another order); such a range is centred in ±0.5
    % of the value (±0.5 at 0), as numpy does for an exactly constant sample.
    """
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return None
    lo, hi = float(finite.min()), float(finite.max())
    half = 0.005 * max(abs(lo), abs(hi)) or 0.5
    if hi - lo > 1e-9 * 2.0 * half:
        return None
    mid = 0.5 * (lo + hi)
    return mid - half, mid + half


def _sensitivity(sens: dict[str, dict[str, float]], path: Path) -> None:
    import matplotlib.pyplot as plt

    outputs = list(sens)
    keys = list(next(iter(sens.values())))
    fig, ax = plt.subplots(figsize=(1.6 + 1.4 * len(keys) * len(outputs) / 2, 3.2))
    width = 0.8 / len(outputs)
    for j, out in enumerate(outputs):
        ax.bar(np.arange(len(keys)) + j * width, [sens[out][k] for k in keys], width, label=out)
    ax.set_xticks(np.arange(len(keys)) + 0.4 - width / 2, keys, fontsize=8)
    ax.axhline(0, color="k", lw=0.6)
    ax.set_ylim(-1, 1)
    ax.set_ylabel("Spearman rank correlation")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def draw_products(maps: dict[str, np.ndarray], target: GridTarget,
                  records: list[dict[str, Any]], sens: dict[str, dict[str, float]],
                  out: Path) -> None:
    """Probability, percentile, distribution and sensitivity pictures into ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    for quantity in ("depth", "pressure", "speed"):
        names = [k for k in maps if k.startswith(f"probability_{quantity}_")]
        _panels(maps, names, target, out / f"probability_{quantity}.png",
                "probability of reaching the threshold", 1.0)
    names = [k for k in maps if k.startswith("peak_depth_")]
    _panels(maps, names, target, out / "peak_depth_percentiles.png", "peak depth [m]", None)
    draw_histograms(records, out / "distributions.png")
    if sens:
        _sensitivity(sens, out / "sensitivity.png")
