"""Sequential Monte Carlo Instant Radiosity (Hedman, Karras, Lehtinen, IEEE TVCG 2016): a VPL set kept from frame
to frame, of which at most M_max = 16 VPLs move per frame, driven toward VPLs of equal intensity I(y) = L(y) / p(y)
(eq. 4, 6), i.e. placed in proportion to their radiosity on the surfaces the camera sees indirectly.

One frame is Algorithm 1 (sec. 3.2):
  3. X: points the camera sees directly (``MethodContext.seen``; a lightmap bake's texels).
  4. INVALID: VPLs whose indirect visibility cannot be verified by mail-boxing (``indirect_visibility``, V = 16,
     two iterations); also VPLs on objects that moved.
  5-6. Candidates: rays in cosine-weighted random directions from X hit 16 I points, resampled 16:1 without
     replacement with weights 1 / p (kNN density among the hits) to an approximately uniform area density.
  7. Their radiosity: 16 paths with next-event estimation seeded per VPL (``vpl_radiosity``).
  8. Their density among the current VPLs with k = 1 (``knn_density``, eq. 7).
  9-12. M_min = min(M_max, M_strong) (eq. 9), M_strong the candidates stronger than the 95th percentile of the
     current VPLs' intensities; the weakest VPLs join INVALID until it holds M_min.
  13-17. At most M_max of INVALID are removed; the strongest candidates fill the budget I.
  18-19. Radiosities (only when the lights, geometry or shading changed: per-VPL seeds make the estimate of an
     unchanged VPL in an unchanged scene the same) and densities with k = max(1, floor(sqrt(I) / 32)) (eq. 8).
The state starts empty; the first frame runs ``warmup`` (100) iterations of the algorithm before its own, so a
chunk of a sequence can start cold anywhere. Not in the paper: the iterations of a cold start after the first (which
fills the empty set), the frame's own included, share ``warmup_rounds`` (16) draws of candidates (lines 3-7: points,
INVALID, candidates, radiosities, the cost of an iteration), each iteration of a round taking its winners out of the
round's candidates; a round ends early at an iteration that moves no VPL (the next ones on the same candidates would
not either). The paper's cold start is ``warmup_rounds = warmup``. Nothing moves during a cold start, so a draw's
candidates stay as good a sample of the indirectly visible surfaces for its iterations; what is lost is the fresh
noise of each iteration's draw (and the "voronoi" areas below average the hits of each draw once). The first
iteration takes every candidate into the empty set, so it estimates no radiosity for choosing them. Radiosities are
estimated in blocks on the tracer's threads. A VPL's intensity for the gather is Lo(y) / (I p(y)) = Lo(y) pi r_k^2 / k:
its outgoing radiance times the area it stands for.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...core.color import luminance
from ...gather.virtual_lights import STANDARD, VirtualLights
from ...materials.surface import Surface, diffuse_bounce
from ...sequence.persisted import record
from ..base import Method, option
from .indirect_visibility import validate
from .knn_density import knn_density, knn_radii, knn_radius, rendering_k
from .vpl_radiosity import estimate_radiosity


SELECTION, RENDERING = 0, 1  # the two random streams of a VPL's radiosity paths
RADIOSITY_BLOCK = 1024  # VPLs per batch of radiosity paths, the batches shared among the tracer's threads


@dataclass
class SMCSettings:
    replacements: int = option(16, label="Moves per Frame", min=1, soft_max=1024,
                               description="VPLs allowed to move between frames (M_max): fewer is steadier, more "
                                           "adapts faster")
    candidate_ratio: int = 16  # intersection points per candidate (16 I points -> I candidates)
    visibility_rays: int = 16  # V: rays per directly visible point toward invalid VPLs
    visibility_iterations: int = 2
    radiosity_samples: int = 16  # paths with next-event estimation per VPL radiosity
    percentile: float = 95.0  # eq. 9: candidates stronger than this percentile of the VPLs count as M_strong
    warmup: int = option(100, label="Warm-up Iterations", min=0, soft_max=1000,
                         description="Iterations run before the first frame of a (cold) sequence")
    # draws of candidates that the warm-up's iterations share (not in the paper; 16 flicker as little as the paper's
    # 100 on the example sequences, at a sixth of its cold start: ``bench/sequence_temporal.py``)
    warmup_rounds: int = option(16, label="Warm-up Draws", min=1, soft_max=100,
                                description="Draws of candidates the warm-up iterations share. 16 starts in "
                                            "about 4 s on a Cornell box and flickers as little "
                                            "as the paper's warm-up (as many draws as iterations), which takes about "
                                            "6 times as long; 4 starts in 1.5 s and flickers 5-8 % more, but its "
                                            "single frames are closer to Cycles")
    camera_points: int = 1024  # |X|: directly visible points per frame (the paper uses every pixel)
    resampling_k: int = 8  # neighbours for the density of the intersection points (the paper does not say)
    density_k: int = 0  # k of the densities for rendering; 0: eq. 8, max(1, floor(sqrt(I) / 32))
    # The area a VPL stands for in the gather, 1 / (I p(y)). "knn": eq. 7 with the k above, as in the paper.
    # "voronoi" (not in the paper): each hit of a round's candidate rays stands for the area pi r^2 / k of its kNN
    # density among the (unselected, so nearly Poisson) hits and gives it to its nearest VPL of the set as it is now,
    # averaged over the last ``area_frames`` rounds (their hits are kept: 16 bytes a hit, 4 KB a VPL). The
    # replacement heuristic keeps VPLs whose neighbours are far, so eq. 7 overestimates their area: the Cornell box
    # comes out a third too bright with "knn"
    area: str = "voronoi"
    area_frames: int = 16
    # k of the hits' kNN areas: k = 1 is unbiased for uniformly random points (E[pi r_1^2] = 1 / density) and the
    # least hurt by corners and edges; its noise averages out over the ~16 hits per VPL and ``area_frames``
    area_k: int = 1

    def __post_init__(self):
        for name in ("replacements", "candidate_ratio", "radiosity_samples", "camera_points", "resampling_k",
                     "area_k", "area_frames", "warmup_rounds"):
            if getattr(self, name) < 1:
                raise ValueError(f"smc {name.replace('_', ' ')} must be at least 1 (got {getattr(self, name)})")
        if self.warmup < 0 or self.visibility_rays < 0 or self.visibility_iterations < 0:
            raise ValueError("smc warm-up, visibility rays and iterations must not be negative")
        if self.area not in ("voronoi", "knn"):
            raise ValueError(f"smc area must be 'voronoi' or 'knn' (got {self.area!r})")
        if not 0.0 <= self.percentile <= 100.0:
            raise ValueError(f"smc percentile must be between 0 and 100 (got {self.percentile})")


@record(fields=("surface", "radiosity", "seed", "mailbox", "strength", "density", "area", "hits", "next_seed",
                "iterations", "stale_radiosity"))
class SMCState:
    """The VPL set Y carried from frame to frame."""

    def __init__(self):
        self.surface: Surface | None = None  # the VPLs as surface points (position, normals, albedo, ...)
        self.radiosity = np.zeros((0, 3))  # Lo(y) per VPL
        self.seed = np.zeros(0, np.int64)  # per-VPL seed of its radiosity paths
        self.mailbox = (np.zeros((0, 3)), np.zeros((0, 3)))  # associated point and its normal
        self.strength = np.zeros(0)  # scalar intensity lum(L) / p used for ranking
        self.density = np.zeros(0)  # p(y) for rendering (eq. 7 with the k of eq. 8)
        self.area = np.zeros(0)  # "voronoi" area per VPL, from the hits below when a frame's lights are made
        self.hits: list[tuple[np.ndarray, np.ndarray]] = []  # each of the last ``area_frames`` rounds' hits:
        # positions and the area each stands for (float32)
        self.next_seed = 0
        self.iterations = 0
        self.stale_radiosity = False  # lights, geometry or shading changed since the radiosities were estimated

    def __len__(self):
        return 0 if self.surface is None else len(self.surface)

    def keep(self, rows) -> None:
        self.surface = self.surface.take(rows)
        self.radiosity, self.seed, self.strength = self.radiosity[rows], self.seed[rows], self.strength[rows]
        self.mailbox = (self.mailbox[0][rows], self.mailbox[1][rows])


def _inside_boxes(points, boxes, margin):
    inside = np.zeros(len(points), bool)
    for lo, hi in boxes:
        inside |= ((points >= lo - margin) & (points <= hi + margin)).all(axis=1)
    return inside


def _candidates(context, s: SMCSettings, points: Surface, count: int):
    """Lines 5-6: hits of random rays from the directly visible points, resampled to about uniform area density:
    (candidate surface, index of the point each came from, (every hit's position, the area it stands for))."""
    rng = context.rng
    origins = rng.integers(0, len(points), s.candidate_ratio * count)
    hits, source, _, _ = diffuse_bounce(context.scene, context.tracer, points.take(origins), rng)
    if len(hits) == 0:
        return hits, source, (np.zeros((0, 3)), np.zeros(0))
    k = min(s.resampling_k, max(len(hits) - 1, 1))
    k_area = min(s.area_k, max(len(hits) - 1, 1))
    r, r_area = knn_radii(hits.position, (k, k_area), context.tracer.threads)
    weight = np.where(np.isfinite(r), r * r, 0.0)
    area = np.where(np.isfinite(r_area), np.pi * r_area * r_area / k_area, 0.0)  # 1 / (M p) per hit: its area
    if not (weight.sum() > 0):
        weight = np.ones(len(hits))
    take = min(count, int((weight > 0).sum()))
    chosen = rng.choice(len(hits), size=take, replace=False, p=weight / weight.sum())
    return hits.take(chosen), origins[source[chosen]], (hits.position, area)


@dataclass
class _Pool:
    """A round's candidates (lines 5-7) that no step has taken yet."""
    surface: Surface
    mailbox: tuple[np.ndarray, np.ndarray]  # the directly visible point each came from, and its normal
    seed: np.ndarray
    radiosity: np.ndarray  # from the SELECTION stream
    rendering: np.ndarray | None = None  # from the RENDERING stream, NaN where not estimated yet

    def __post_init__(self):
        self.rendering = np.full((len(self.seed), 3), np.nan)

    def remove(self, rows) -> None:
        keep = np.setdiff1d(np.arange(len(self.seed)), rows)
        self.surface, self.seed, self.radiosity = self.surface.take(keep), self.seed[keep], self.radiosity[keep]
        self.rendering, self.mailbox = self.rendering[keep], (self.mailbox[0][keep], self.mailbox[1][keep])

    def rendering_radiosity(self, context, s: SMCSettings, rows: np.ndarray, strength: np.ndarray) -> np.ndarray:
        """The RENDERING radiosities of the candidates ``rows``, the strongest by ``strength`` among them: those
        not estimated yet are, with the next strongest up to 4 M_max (the next iterations' likely winners), in one
        batch (a VPL's estimate does not depend on its batch)."""
        missing = np.isnan(self.rendering[rows, 0])
        if missing.any():
            todo = np.nonzero(np.isnan(self.rendering[:, 0]))[0]
            todo = todo[np.argsort(-strength[todo], kind="stable")[:max(int(missing.sum()), 4 * s.replacements)]]
            self.rendering[todo] = _radiosity(context, s, self.surface.take(todo), self.seed[todo], RENDERING)
        return self.rendering[rows]


def iterate(state: SMCState, context, settings, motion=None, steps: int = 1) -> None:
    """Algorithm 1 over ``state``: lines 3-7 (directly visible points X, INVALID, candidates and their radiosities)
    once, then lines 8-19 ``steps`` times on those candidates, each step taking its winners out of them. One step
    is one frame of the paper; a warm-up round takes several (``SMCSettings.warmup_rounds``)."""
    s: SMCSettings = settings.smc
    budget = max(1, int(settings.vpls))
    scene, rng = context.scene, context.rng
    extent = float(np.linalg.norm(np.subtract(*scene.bounds)))
    points = context.seen(s.camera_points, rng).surface  # X
    if len(points) == 0:
        return
    valid = _verified(state, context, s, points, motion, extent)
    cand, source, covered = _candidates(context, s, points, budget)
    seeds = state.next_seed + np.arange(len(cand), dtype=np.int64)
    state.next_seed += len(cand)
    # an empty set takes every candidate (at most I), so their intensities need no radiosity
    radiosity = _radiosity(context, s, cand, seeds, SELECTION) if len(state) else np.zeros((len(cand), 3))
    pool = _Pool(cand, (points.position[source], points.geometric_normal[source]), seeds, radiosity)
    for _ in range(steps):
        moved = _step(state, context, settings, pool, valid, extent)
        if moved is None:  # nothing changed: neither would the next steps on the same candidates
            break
        valid = moved
    if s.area == "voronoi" and len(covered[0]):
        _remember_hits(state, s, covered, motion, extent)
    state.iterations += steps


def _remember_hits(state: SMCState, s: SMCSettings, covered, motion, extent: float) -> None:
    """Keeps this round's hits for the "voronoi" areas, with those of the ``area_frames - 1`` rounds before; where
    objects moved, this round's hits stand in for the earlier rounds' (which lie where the surfaces were)."""
    position, area = covered[0].astype(np.float32), covered[1].astype(np.float32)
    if motion is not None and motion.boxes and state.hits:
        margin = 1e-4 * max(extent, 1e-12)
        inside = _inside_boxes(position, motion.boxes, margin)
        kept = [(p, a, ~_inside_boxes(p, motion.boxes, margin)) for p, a in state.hits]
        state.hits = [(np.concatenate([p[out], position[inside]]), np.concatenate([a[out], area[inside]]))
                      for p, a, out in kept]
    state.hits = (state.hits + [(position, area)])[-s.area_frames:]


def _voronoi_areas(state: SMCState, workers: int) -> np.ndarray:
    """The "voronoi" areas: each remembered hit gives the area it stands for to its nearest VPL of the set as it is
    now, averaged over the rounds. (A running mean of each round's shares would keep old cells: where VPLs join,
    their neighbours' larger cells, and the replacements put VPLs where light is strong, so the sum would come out
    10 % too bright on cornell_area.)"""
    if not len(state) or not state.hits:
        return np.zeros(len(state))
    _, nearest = cKDTree(state.surface.position).query(np.concatenate([p for p, _ in state.hits]), workers=workers)
    share = np.bincount(nearest, weights=np.concatenate([a for _, a in state.hits]), minlength=len(state))
    return share / len(state.hits)


def _radiosity(context, s: SMCSettings, surface: Surface, seeds, stream) -> np.ndarray:
    """Lines 7 and 18: ``estimate_radiosity`` in blocks of RADIOSITY_BLOCK VPLs on the tracer's threads (a VPL's
    estimate does not depend on the others in its batch; fixed blocks keep the batches, so the threads do not change
    the estimates)."""
    def block(lo):
        rows = slice(lo, lo + RADIOSITY_BLOCK)
        return estimate_radiosity(context.scene, context.tracer, context.lights, surface.take(rows), seeds[rows],
                                  s.radiosity_samples, max(1, context.max_bounces), stream)
    starts = range(0, len(surface), RADIOSITY_BLOCK)
    if len(starts) < 2 or context.tracer.threads < 2:
        return np.concatenate([np.zeros((0, 3)), *map(block, starts)])
    with ThreadPoolExecutor(min(context.tracer.threads, len(starts))) as pool:
        return np.concatenate(list(pool.map(block, starts)))


def _verified(state: SMCState, context, s: SMCSettings, points: Surface, motion, extent: float) -> np.ndarray:
    """Line 4: the VPLs verified indirectly visible (mail-boxing) and not on an object that moved; their mailboxes
    follow the points that verified them."""
    if not len(state):
        return np.zeros(0, bool)
    valid, box_p, box_n = validate(context.scene.camera, context.tracer, state.surface.position,
                                   state.surface.shading_normal, *state.mailbox, points.position,
                                   points.geometric_normal, context.rng, s.visibility_rays, s.visibility_iterations)
    if motion is not None and motion.boxes:
        valid &= ~_inside_boxes(state.surface.position, motion.boxes, 1e-4 * max(extent, 1e-12))
    state.mailbox = (box_p, box_n)
    return valid


def _step(state: SMCState, context, settings, pool: _Pool, valid: np.ndarray, extent: float) -> np.ndarray | None:
    """Lines 8-19 with the candidates left in ``pool``: their k = 1 densities among the current VPLs (eq. 7),
    M_min (eq. 9), at most M_max VPLs out, the strongest candidates in, the VPLs' densities for rendering (eq. 8).
    Returns ``valid`` for the VPLs after the step (the new ones are valid), None if the step changed nothing."""
    s: SMCSettings = settings.smc
    budget = max(1, int(settings.vpls))
    floor = 1e-6 * max(extent, 1e-12)
    if len(state):
        density = knn_density(pool.surface.position, state.surface.position, 1, budget, floor=floor)
    else:
        density = knn_density(pool.surface.position, pool.surface.position, 1, budget, exclude_self=True,
                              floor=floor)
    strength = luminance(pool.radiosity) / np.where(np.isfinite(density) & (density > 0), density, np.inf)
    leave = _leaving(state, valid, strength, s)
    before = len(state)
    if not len(leave) and (before >= budget or not len(pool.seed)) and not state.stale_radiosity:
        return None
    if before:
        kept = np.setdiff1d(np.arange(before), leave)
        state.keep(kept)
        valid = valid[kept]
    room = budget - len(state)
    if room > 0 and len(pool.seed):
        best = np.argsort(-strength, kind="stable")[:room]
        _admit(state, context, s, pool, best, strength)
        valid = np.concatenate([valid, np.ones(len(best), bool)])
        pool.remove(best)
        if len(leave) and len(best) >= len(leave):  # new VPLs take the slots of those they replace
            dest = np.concatenate([kept, leave, before + np.arange(len(best) - len(leave))])
            order = np.argsort(dest)
            state.keep(order)
            valid = valid[order]
    if state.stale_radiosity and len(state):  # line 18 where the scene changed
        state.radiosity = _radiosity(context, s, state.surface, state.seed, RENDERING)
    state.stale_radiosity = False
    if len(state):
        _rendering_density(state, s, budget, floor, extent)
    return valid


def _leaving(state: SMCState, valid: np.ndarray, strength: np.ndarray, s: SMCSettings) -> np.ndarray:
    """Lines 9-13: INVALID, topped up with the weakest valid VPLs to M_min = min(M_max, M_strong) (eq. 9, M_strong
    the candidates stronger than the percentile of the VPLs' intensities); at most M_max of them, sorted."""
    invalid = np.nonzero(~valid)[0]
    invalid = invalid[np.argsort(state.strength[invalid], kind="stable")]
    m_min = min(s.replacements, int((strength > np.percentile(state.strength, s.percentile)).sum())) \
        if len(state) else 0
    if len(invalid) < m_min:
        weakest = np.nonzero(valid)[0]
        weakest = weakest[np.argsort(state.strength[weakest], kind="stable")]
        invalid = np.concatenate([invalid, weakest[:m_min - len(invalid)]])
    return np.sort(invalid[:s.replacements])


def _admit(state: SMCState, context, s: SMCSettings, pool: _Pool, best: np.ndarray, strength: np.ndarray):
    """Lines 14-17: the candidates ``best``, the strongest by ``strength`` (of every candidate of the pool), join
    the set (at its end)."""
    new = pool.surface.take(best)
    state.surface = new if state.surface is None else Surface.concat([state.surface, new])
    # the radiosity that lights the image comes from the VPL's other stream: the one it was chosen by is biased
    # upward by the choice (a candidate wins on a lucky estimate); estimated at line 18 if all are stale
    state.radiosity = np.concatenate([state.radiosity, np.zeros((len(best), 3)) if state.stale_radiosity else
                                      pool.rendering_radiosity(context, s, best, strength)])
    state.seed = np.concatenate([state.seed, pool.seed[best]])
    state.mailbox = (np.concatenate([state.mailbox[0], pool.mailbox[0][best]]),
                     np.concatenate([state.mailbox[1], pool.mailbox[1][best]]))
    state.strength = np.concatenate([state.strength, strength[best]])


def _rendering_density(state: SMCState, s: SMCSettings, budget: int, floor: float, extent: float) -> None:
    """Line 19: p(y) of eq. 7 with the k of eq. 8, and the intensities lum(L) / p that rank the VPLs."""
    k = s.density_k or rendering_k(budget)
    r = knn_radius(state.surface.position, state.surface.position, k, exclude_self=True)
    r = np.where(np.isfinite(r), np.maximum(r, floor), max(extent, 1e-12))  # too few VPLs: the scene's size
    state.density = k / (budget * np.pi * r * r)
    state.strength = luminance(state.radiosity) / state.density


def start(context, settings) -> SMCState:
    return SMCState()


def advance(state: SMCState, context, settings, motion) -> tuple[VirtualLights, dict]:
    """The frame's VPLs: this frame's iteration, after a cold start the last of ``warmup`` + 1 (``warmup_rounds``)."""
    rays0 = context.tracer.rays_traced
    if state.iterations and motion is not None and motion.static():  # nothing moved: the same VPLs, no rays
        lights = as_virtual_lights(state, settings.vpls, settings.smc.area)
        return lights, {"vpls": len(lights), "replaced": 0, "light_paths": 0, "iterations": state.iterations,
                        "sampling_rays": 0, "reused": True}
    if motion is None or motion.first or motion.lights_changed or motion.geometry_changed or motion.shading_changed:
        state.stale_radiosity = True
    moved, before = len(state), set(state.seed.tolist())
    for steps in warmup_rounds(settings.smc) if state.iterations == 0 else [1]:
        iterate(state, context, settings, motion, steps)
    replaced = len(set(state.seed.tolist()) - before)
    if settings.smc.area == "voronoi":
        state.area = _voronoi_areas(state, context.tracer.threads)
    lights = as_virtual_lights(state, settings.vpls, settings.smc.area)
    return lights, {"vpls": len(lights), "replaced": replaced if moved else len(lights), "light_paths": 0,
                    "iterations": state.iterations, "sampling_rays": context.tracer.rays_traced - rays0}


def warmup_rounds(s: SMCSettings) -> list[int]:
    """The iterations of each round of a cold start: one that fills the empty set, then the ``warmup`` others, the
    frame's own the last, split as evenly as they go into at most ``s.warmup_rounds`` rounds. Nothing moves between
    them, so the frame's iteration is a warm-up iteration like the others."""
    rounds = min(s.warmup_rounds, s.warmup)
    return [1] + [s.warmup // rounds + (i < s.warmup % rounds) for i in range(rounds)]


def as_virtual_lights(state: SMCState, budget: int, settings_area: str = "voronoi") -> VirtualLights:
    if not len(state):
        return VirtualLights.empty()
    area = state.area if settings_area == "voronoi" else 1.0 / (max(1, int(budget)) * state.density)
    surf = state.surface
    return VirtualLights(surf.position.copy(), surf.smooth_normal.copy(), state.radiosity * area[:, None],
                         np.ones(len(state), np.int32), np.full(len(state), STANDARD, np.int8), state.seed.copy())


def place(context, settings):
    """A single frame: a cold start with its warm-up."""
    from ...sequence.motion import Motion
    return advance(start(context, settings), context, settings, Motion(first=True))


# A VPL keeps its slot in the set while it lives (a new one takes the slot of the one it replaces), so the sequence
# keeps the gather's order of the slots from frame to frame: each VPL stays in its interleaving subset.
METHOD = Method(
    "smc", "Sequential Monte Carlo IR", "Hedman et al. 2016: VPLs kept from frame to frame where the camera sees "
                                        "them indirectly, at most a few moved per frame (stable animations)",
    place, SMCSettings, start=start, advance=advance, stable_lights=True)
