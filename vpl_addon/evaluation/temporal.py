"""Error and temporal instability of an animation against per-frame references (Hedman, Karras, Lehtinen,
Sequential Monte Carlo Instant Radiosity, sec. 5, Table 1 and eq. 10).

Both images are tone mapped first (Reinhard et al.'s global operator L / (1 + L) on luminance), "to make the
results agree better with perceived quality". Per pixel p and frame t the error is
``Error(p, t) = T(I(p, t)) - T(I_ref(p, t))``; |E| is its mean absolute value and |E'| the mean absolute finite
difference over time, ``E' = ΔError / Δt`` (eq. 10, Δt = one frame), which measures flickering. Both are reported
over the tracked pixels (Hedman et al. track 8) and over every pixel the references cover fully in every frame.
"""
from __future__ import annotations

import numpy as np

from ..core.color import luminance
from .metrics import FULL_COVERAGE

TRACKED_PIXELS = 8


def reinhard(value: np.ndarray) -> np.ndarray:
    """Reinhard et al.'s global tone mapping L / (1 + L) (negative values clamp to 0)."""
    value = np.maximum(np.asarray(value, np.float64), 0.0)
    return value / (1.0 + value)


def tracked_pixels(mask: np.ndarray, count: int = TRACKED_PIXELS, seed: int = 0) -> np.ndarray:
    """``count`` flat pixel indices inside ``mask``, spread over it: one random pixel from each of ``count`` equal
    slices of the masked pixels in scanline order (fixed seed: the same pixels for every method)."""
    inside = np.flatnonzero(mask)
    if len(inside) == 0:
        return inside
    count = min(count, len(inside))
    edges = np.linspace(0, len(inside), count + 1).astype(int)
    rng = np.random.default_rng(seed)
    return inside[[rng.integers(a, b) for a, b in zip(edges[:-1], edges[1:])]]


def sequence_mask(reference_alphas: list[np.ndarray | None], shape: tuple[int, int]) -> np.ndarray:
    """Pixels every reference frame covers fully."""
    mask = np.ones(shape, bool)
    for alpha in reference_alphas:
        if alpha is not None:
            mask &= np.asarray(alpha).reshape(shape) >= FULL_COVERAGE
    return mask


def temporal_errors(images: list[np.ndarray], references: list[np.ndarray], mask: np.ndarray | None = None,
                    tracked: np.ndarray | None = None) -> dict:
    """|E| and |E'| of a sequence of (H,W,C) images against references of the same frames, over the tracked pixels
    and over the whole (masked) frame; also |E| of every frame."""
    if len(images) != len(references) or not images:
        raise ValueError(f"{len(images)} frames against {len(references)} references: need the same, at least one")
    shape = np.asarray(references[0]).shape[:2]
    for i, (a, b) in enumerate(zip(images, references)):
        if np.asarray(a).shape[:2] != shape or np.asarray(b).shape[:2] != shape:
            raise ValueError(f"frame {i}: image {np.asarray(a).shape[:2]} and reference {np.asarray(b).shape[:2]} "
                             f"differ from {shape}")
    mask = np.ones(shape, bool) if mask is None else np.asarray(mask, bool)
    if not mask.any():
        raise ValueError("no pixel is fully covered in every reference frame: nothing to compare")
    tracked = tracked_pixels(mask) if tracked is None else np.asarray(tracked)
    error = np.stack([reinhard(luminance(a)) - reinhard(luminance(b)) for a, b in zip(images, references)])
    error = error.reshape(len(images), -1)  # (frames, pixels)
    change = np.abs(np.diff(error, axis=0))

    def summary(pixels):
        out = {"E": float(np.abs(error[:, pixels]).mean())}
        out["E_prime"] = float(change[:, pixels].mean()) if len(change) else 0.0
        return out

    inside = np.flatnonzero(mask)
    return {"frames": len(images), "tracked": summary(tracked), "frame": summary(inside),
            "tracked_pixels": [int(p) for p in tracked], "pixels": int(len(inside)),
            "E_per_frame": [float(v) for v in np.abs(error[:, inside]).mean(axis=1)]}
