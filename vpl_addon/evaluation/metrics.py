"""Error of an image against a reference, over the pixels the reference covers fully.

rMAE as in Li et al. (Virtual Blue Noise Lighting, sec. 5): |I - I_ref| / (I_ref + 0.01 mean(I_ref)), averaged
over masked pixels and channels; relMSE the squared analogue; RMSE after Reinhard tone mapping x / (1 + x);
mean ratio = mean(I) / mean(I_ref). ``rmae4`` is rMAE after both images are averaged over 4 x 4 pixel blocks (the
blocks the mask holds whole): a reference's own noise there is about a quarter of its per-pixel noise, while a
method's bias, and the blotches a denoiser leaves, stay (the corridor's 16384-spp reference differs from itself
denoised by rMAE 0.066 per pixel, 0.014 in blocks). ``clean_rrmse`` takes that noise out
altogether, given a second reference (a twin) with noise of its own; ``noise_floor`` says, from the same twin, what
the truth itself scores in rMAE, under which no image's figure goes. The mask keeps pixels whose reference
alpha is at least 0.999: silhouette pixels have random coverage and would dominate the error of a pass that
Cycles divides by a colour. For those passes (``Diffuse Direct`` / ``Diffuse Indirect`` by ``Diffuse Color``, the
glossy ones by ``Glossy Color``) the pixels whose reference colour is 0 (metals for the diffuse passes, diffuse
surfaces for the glossy ones) are left out as well: Cycles writes 0 there by convention, the pass is undefined
and the composite ignores it.
"""
from __future__ import annotations

import numpy as np

FULL_COVERAGE = 0.999
BLOCK = 4  # the side of the pixel blocks of ``rmae4``


def coverage_mask(reference_alpha: np.ndarray | None, shape: tuple[int, int]) -> np.ndarray:
    if reference_alpha is None:
        return np.ones(shape, bool)
    return np.asarray(reference_alpha).reshape(shape) >= FULL_COVERAGE


DIVIDED_BY = {"Diffuse Direct": "Diffuse Color", "Diffuse Indirect": "Diffuse Color",
              "Glossy Direct": "Glossy Color", "Glossy Indirect": "Glossy Color"}  # Cycles' pass divisions


def pass_mask(name: str, reference: dict, mask: np.ndarray) -> np.ndarray:
    """``mask`` without the pixels where pass ``name`` is undefined in the reference passes ``reference``: for a
    pass Cycles divides by a colour (``DIVIDED_BY``), where that colour is 0."""
    color = reference.get(DIVIDED_BY.get(name))
    if color is None:
        return mask
    return mask & (np.asarray(color)[..., :3].max(axis=-1) > 0.0)


def block_means(image: np.ndarray, k: int) -> np.ndarray:
    """(H // k, W // k, C) means of the k x k blocks of an (H,W,C) image (the last partial rows and columns left
    out)."""
    h, w, c = image.shape[0] // k, image.shape[1] // k, image.shape[2]
    return image[:h * k, :w * k].reshape(h, k, w, k, c).mean(axis=(1, 3)) if h and w else np.zeros((h, w, c))


def _rmae(img: np.ndarray, ref: np.ndarray) -> float:
    eps = 0.01 * float(ref.mean()) if ref.mean() > 0 else 1e-8
    return float(np.mean(np.abs(img - ref) / (ref + eps)))


def _rgb(image: np.ndarray, *references: np.ndarray) -> list[np.ndarray]:
    """The RGB of ``image`` and of the ``references`` it is judged against, in float64; a ValueError naming their
    sizes where they differ."""
    img, *refs = (np.asarray(x, np.float64)[..., :3] for x in (image, *references))
    if any(r.shape != img.shape for r in refs):
        sizes = " and ".join(f"{r.shape[1]}x{r.shape[0]}" for r in refs)
        are = "references are" if len(refs) > 1 else "reference is"
        raise ValueError(f"image is {img.shape[1]}x{img.shape[0]} but the {are} {sizes}")
    return [img, *refs]


def _inside(mask: np.ndarray, *images: np.ndarray) -> list[np.ndarray]:
    """Each image's pixels in ``mask``; a ValueError where the mask holds none."""
    if not mask.any():
        raise ValueError("no pixel is fully covered in the reference: nothing to compare")
    return [x[mask] for x in images]


def errors(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> dict[str, float]:
    """rMAE, relMSE, Reinhard RMSE, mean ratio and rMAE of 4 x 4 blocks (``rmae4``; of the pixels if no block is
    whole) of (H,W,C) ``image`` against ``reference`` (RGB only)."""
    img, ref = _rgb(image, reference)
    mask = np.ones(ref.shape[:2], bool) if mask is None else mask
    whole = block_means(mask[..., None].astype(np.float64), BLOCK)[..., 0] >= 1.0
    img_blocks, ref_blocks = block_means(img, BLOCK)[whole], block_means(ref, BLOCK)[whole]
    img, ref = _inside(mask, img, ref)
    ref_mean = float(ref.mean())
    eps = 0.01 * ref_mean if ref_mean > 0 else 1e-8
    diff = img - ref
    tone = img / (1.0 + np.maximum(img, 0.0)) - ref / (1.0 + np.maximum(ref, 0.0))
    if ref_mean > 0:
        ratio = float(img.mean() / ref_mean)
    else:
        ratio = 1.0 if img.mean() == 0 else float("inf")
    rmae = _rmae(img, ref)
    return {
        "rmae": rmae,
        "relmse": float(np.mean(diff * diff / (ref * ref + eps * eps))),
        "rmse_reinhard": float(np.sqrt(np.mean(tone * tone))),
        "mean_ratio": ratio,
        "rmae4": _rmae(img_blocks, ref_blocks) if img_blocks.size else rmae,
        "pixels": int(mask.sum()),
    }


def clean_rrmse(image: np.ndarray, reference: np.ndarray, twin: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Relative RMSE of (H,W,C) ``image`` against the truth the references stand for, with their own noise taken
    out: ``reference`` and ``twin`` are two renders of the same scene with independent noise (Cycles with two
    seeds), M their mean. For an image whose noise is independent of theirs, E[(I - M)^2] = (I - T)^2 + Var(M)
    and E[(A - B)^2] / 4 = Var(M) per pixel and channel, so

        sqrt(max(0, mean((I - M)^2) - mean((A - B)^2) / 4)) / mean(M)

    estimates the error against the truth T without bias in the squared error (RGB only, over ``mask``). Per-pixel
    metrics against one reference (rMAE) keep its noise in every figure: the corridor's 16384-spp reference
    differs from a second one by rMAE 0.095, so a perfect picture scores about 0.067 there."""
    img, a, b = _rgb(image, reference, twin)
    img, a, b = _inside(np.ones(a.shape[:2], bool) if mask is None else mask, img, a, b)
    mean = 0.5 * (a + b)
    scale = max(float(mean.mean()), 1e-8)  # black references: as ``errors``' floor, an absolute error over 1e-8
    squared = float(np.mean((img - mean) ** 2) - 0.25 * np.mean((a - b) ** 2))
    return float(np.sqrt(max(squared, 0.0)) / scale)


def noise_floor(reference: np.ndarray, twin: np.ndarray, mask: np.ndarray | None = None) -> dict[str, float]:
    """What the truth itself scores against ``reference``, in ``errors``' rMAE and block rMAE: the floor under every
    image's figure. The reference is A = T + n and its ``twin`` B = T + n', with n and n' independent and alike
    (Cycles with two seeds). For Gaussian noise (a pixel's mean over thousands of samples) E|A - B| = sqrt(2)
    E|A - T|, so the truth scores the twin's rMAE over sqrt(2); whatever the noise's shape, at least half of it
    (|A - B| <= |A - T| + |T - B|). An image independent of the reference cannot do better in expectation where
    the noise is symmetric about T (the median minimises the mean absolute deviation), so an rMAE ratio between two
    renderers is bounded by the rival's figure over this floor. ``rmae_bound`` is the half; ``clean_rrmse`` has no
    floor (it takes the noise out)."""
    found = errors(twin, reference, mask)
    return {"rmae": found["rmae"] / np.sqrt(2.0), "rmae_bound": found["rmae"] / 2.0,
            "rmae4": found["rmae4"] / np.sqrt(2.0)}


def error_map(image: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-pixel relative absolute error (H,W), the quantity rMAE averages."""
    img = np.asarray(image, np.float64)[..., :3]
    ref = np.asarray(reference, np.float64)[..., :3]
    eps = 0.01 * max(float(ref.mean()), 1e-8)
    return np.mean(np.abs(img - ref) / (ref + eps), axis=2)
