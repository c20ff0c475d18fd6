"""``compare``: the error of every pass of a render against a Cycles reference, as a JSON-ready dict."""
from __future__ import annotations

import numpy as np

from . import passes as P
from .exr import read_passes
from .metrics import coverage_mask, error_map, errors, pass_mask


def compare_files(image_path: str, reference_path: str, names: list[str] | None = None,
                  heatmap: str | None = None) -> dict:
    image, _ = read_passes(image_path)
    reference, _ = read_passes(reference_path)
    common = [n for n in (names or image) if n in image and n in reference]
    if not common:
        raise ValueError(f"no pass in common: {image_path} has {sorted(image)}, {reference_path} has "
                         f"{sorted(reference)}")
    ref_alpha = reference[P.COMBINED][..., 3] if P.COMBINED in reference and reference[P.COMBINED].shape[2] == 4 \
        else None
    any_ref = reference[common[0]]
    mask = coverage_mask(ref_alpha, any_ref.shape[:2])
    result = {name: errors(image[name], reference[name], pass_mask(name, reference, mask)) for name in common}
    if heatmap:
        focus = next((n for n in (P.DIFFUSE_INDIRECT, P.DIFFUSE_DIRECT) if n in common), common[0])
        write_heatmap(heatmap, error_map(image[focus], reference[focus]), pass_mask(focus, reference, mask),
                      f"{focus}: relative error")
    return result


def write_heatmap(path: str, err: np.ndarray, mask: np.ndarray, title: str) -> None:
    """A PNG of the per-pixel relative error (0 to 1 on the colour scale; grey where masked out)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    shown = np.ma.masked_where(~mask, err)
    fig, ax = plt.subplots(figsize=(5, 4.2), dpi=100)
    cmap = matplotlib.colormaps["inferno"].with_extremes(bad="0.5")
    im = ax.imshow(shown, cmap=cmap, vmin=0.0, vmax=1.0, interpolation="nearest")
    ax.set_title(f"{title}, rMAE {float(np.mean(err[mask])) if mask.any() else float('nan'):.4f}")
    ax.axis("off")
    fig.colorbar(im, ax=ax, fraction=0.046)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)
