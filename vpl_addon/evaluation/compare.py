"""``compare``: the error of every pass of a render against a Cycles reference, as a JSON-ready dict."""
from __future__ import annotations

import numpy as np

from ..core import passes as P
from ..core.exr import read_passes
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
    masks = {name: pass_mask(name, reference, mask) for name in common}
    if names is None:  # all passes: leave out those undefined everywhere (the glossy ones of a diffuse scene)
        common = [n for n in common if masks[n].any()] or common
    result = {name: errors(image[name], reference[name], masks[name]) for name in common}
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


SEQUENCE_PASSES = (P.DIFFUSE_INDIRECT,)  # what Hedman et al. measure: the indirect light


def sequence_frames(folder: str) -> dict[int, str]:
    """Frame number -> path of every ``frame_NNNN.exr`` (a bake's output, or references named the same way)."""
    import os
    import re
    found = {}
    for name in os.listdir(folder):
        m = re.fullmatch(r"frame_(-?\d+)\.exr", name)
        if m:
            found[int(m.group(1))] = os.path.join(folder, name)
    return dict(sorted(found.items()))


def compare_sequences(image_dir: str, reference_dir: str, names: list[str] | None = None) -> dict:
    """|E| and |E'| after Reinhard tone mapping (``temporal``) of the frames both folders hold, per pass, with
    each frame's rMAE; frames must be consecutive."""
    from .temporal import sequence_mask, temporal_errors
    images, references = sequence_frames(image_dir), sequence_frames(reference_dir)
    frames = [f for f in images if f in references]
    if not frames:
        raise ValueError(f"no frame in common: {image_dir} has {len(images)} frame_NNNN.exr, {reference_dir} "
                         f"has {len(references)}")
    if frames != list(range(frames[0], frames[-1] + 1)):
        raise ValueError(f"frames {frames[0]}..{frames[-1]} are not consecutive in both folders")
    loaded = [(read_passes(images[f])[0], read_passes(references[f])[0]) for f in frames]
    common = [n for n in (names or SEQUENCE_PASSES) if all(n in a and n in b for a, b in loaded)]
    if not common:
        raise ValueError(f"no pass {', '.join(names or SEQUENCE_PASSES)} in every frame of both folders")
    alphas = [ref[P.COMBINED][..., 3] if P.COMBINED in ref and ref[P.COMBINED].shape[2] == 4 else None
              for _, ref in loaded]
    mask = sequence_mask(alphas, loaded[0][1][common[0]].shape[:2])
    result = {}
    for name in common:
        result[name] = temporal_errors([a[name] for a, _ in loaded], [b[name] for _, b in loaded], mask)
        result[name]["first_frame"] = frames[0]
        result[name]["rmae_per_frame"] = [errors(a[name], b[name], mask)["rmae"] for a, b in loaded]
    return result
