"""Virtual Blue Noise Lighting (Li, Wang, Lin, Yuksel, HPG 2022): lights placed from the camera, thinned to blue
noise, lit by photon splitting, and sampled with MIS and camera path extension when rendering.

``place`` follows sec. 3:
1. candidates (sec. 3.1): M = ``candidates`` x N camera samples, the same number in every pixel; at each primary
   hit x a BSDF-sampled ray (the glossy lobe with its share of the albedo, else cosine) finds y, a point the
   gather can see: the candidate if y has a diffuse colour; on pure metal the camera path goes on (Fig. 6b), up to
   ``SPECULAR_EXTENSION`` times. Lights hold diffusely reflected light only: a metallic lobe's light is found by
   extending the camera path through it when rendering (``virtual_light_sampling``), so no light sits on metal
   and no directional emission profile is needed (a deviation from sec. 3.3's 16x16 octahedral maps).
2. adaptive sample elimination (sec. 3.2, ``sample_elimination``) keeps N with radii r = alpha r_max;
3. photon splitting (sec. 3.3, ``Splitting``): ``photons`` light paths, traced in batches on a thread of their own
   while steps 1-2 run (they do not depend on the lights; at most ``AHEAD`` batches are held) and on all the
   tracer's threads after them, share the intensity of every vertex among the lights covering it, kept apart by
   bounce so that an extended camera path uses only light of as many fewer bounces as it has extra vertices (the
   scene's bounce limit holds for the whole path); with the catchments' shapes, their moments give each light a
   slope across its disc (``photon_lights.fit_slopes``). The caustic photons of sharp glossy lobes are shared
   once more, apart (``paths.light_paths``); those of the distant lights come from paths aimed at the sharp
   surfaces (``methods.vbnl.caustic_photons``).
``gather`` is ``virtual_light_sampling.gather`` (sec. 4), run ``gather_samples`` times per pixel.

In a sequence the photons' light paths are kept from frame to frame and verified against moving objects and lights
(``sequence.path_verification``, Moreau et al.); the lights are placed and the photons split among them again in every
frame in which something moved (the camera included), the candidates and catchments with the camera's numbers
(``MethodContext.camera_rng``, the same in every frame), so that where the view did not change the lights land where
they were and only their light changes (``bench/sequence_temporal.py --picture`` measures the flicker this
steadies). The candidates are found in the scene without the objects that move
in the sequence (``view_candidates``), so an object moving through the view leaves the lights where they were.
"""
from __future__ import annotations

import math
import threading
import time
from collections import deque
from contextlib import nullcontext
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from functools import partial
from itertools import chain, islice
from typing import NamedTuple

import numpy as np

from ...core.color import largest, luminance
from ...core.sampling import concentric_disk, cosine_hemisphere, dot, orthonormal_basis, stratified_2d
from ...gather.virtual_lights import VirtualLights
from ...materials.microfacet import GlossyLobe
from ...materials.surface import Surface, bounce, diffuse_bounce, shade
from ...paths.gbuffer import GBuffer
from ...paths.light_paths import trace_paths
from ...sequence.path_verification import PlacedFromPaths, follow
from ..base import Method, option
from . import virtual_light_sampling
from .caustic_photons import AimedLights, aimed_lights, distant_caustics, trace_caustic_photons
from .photon_lights import ALPHA, LID, SECTORS, SLAB, PhotonLights, Splitting, fit_slopes, lid_heights, sector_angle, \
    sector_of
from .sample_elimination import MODES, eliminate

PATHS_PER_BATCH = 1 << 16
PIXELS_PER_BATCH = 1 << 14
POINTS_PER_BATCH = 1 << 18
DROP = SLAB  # catchment rays start this many radii above the light's tangent plane: its whole slab
SPECULAR_EXTENSION = 4  # metal surfaces a candidate's camera path may pass before it gives up
LIFT = 0.05  # a light's reach is found by rays this many radii above its plane (``open_reach``)
REFINE = 16  # catchment points, as a multiple, for a light that few of its first points found (``catchment``)
AHEAD = 8  # batches of photons traced before their lights exist (about 80 MB at PATHS_PER_BATCH)
AUTO_PATHS = (1 << 18, 1 << 20)  # the automatic light paths' range (``VBNLSettings.light_paths``)
ELIMINATION = (("adaptive", "Adaptive", "Blue noise that keeps the density the camera asks for (eq. 2)"),
               ("uniform", "Uniform", "Blue noise with one radius everywhere (eq. 1)"),
               ("none", "None", "A random subset of the candidates"))


@dataclass
class VBNLSettings:
    candidates: int = 10  # M / N: camera candidates per kept light
    elimination: str = option("adaptive", prop="elimination", label="Sample Elimination", items=ELIMINATION,
                              description="How the VBNL candidates are thinned to the light budget")
    local: int = 32  # m of eq. 2: the neighbours that estimate a candidate's local density
    # light paths traced for photon splitting; 0: automatic (``light_paths``)
    photons: int = option(0, prop="photons", label="Light Paths", min=0, soft_max=1 << 26,
                          description="Light paths traced to light the virtual lights (VBNL photon splitting): more "
                                      "is smoother; 0 = automatic, a quarter of the render's camera samples (pixels "
                                      "x Samples / 4), from 262144 to 1048576")
    area_samples: int = 32  # surface points per light that measure its catchment
    # aimed caustic light paths per light path (``methods.vbnl.caustic_photons``), 0: none. On the helmet under its HDR,
    # 2 seeds, a quarter takes the 8 x 8-block rMAE of Diffuse Indirect to 0.29 (as many: 0.27; none: 0.45-0.57;
    # Cycles at 64 spp: 0.49)
    aimed_caustics: float = 0.25
    sampling: virtual_light_sampling.SamplingSettings = field(
        default_factory=virtual_light_sampling.SamplingSettings)

    def __post_init__(self):
        if self.elimination not in MODES:
            raise ValueError(f"unknown sample elimination {self.elimination!r}; choose one of {', '.join(MODES)}")
        if self.candidates < 1 or self.photons < 0 or self.sampling.samples < 0 or not self.aimed_caustics >= 0.0:
            raise ValueError("vbnl needs candidates >= 1, photons >= 0 (0: automatic), gather samples >= 0 (0: one "
                             "per camera sample) and aimed caustics >= 0")

    def light_paths(self, camera_samples: int) -> int:
        """The light paths a render with ``camera_samples`` in all (pixels x samples per pixel) traces: ``photons``,
        or if that is 0 a quarter of the camera samples within ``AUTO_PATHS``. Photon splitting gives each light the
        photons of its catchment, 64 a light at 2^18 paths and 4096 lights, so each light's intensity carries a few
        per cent of noise and the image a blotch per light, which more camera samples and the denoiser leave; four
        times the paths take a fifth off cornell_sun's error in 4 x 4 blocks at 64 samples and a tenth off
        cornell_area's (``bench/block_error.py``). Tied to the camera samples, they cost the same share
        of the render at any size, and leave renders of up to 16 samples at 256 x 256 as they were."""
        return self.photons or int(np.clip(camera_samples // 4, *AUTO_PATHS))


def _bsdf_bounce(scene, tracer, x, rng: np.random.Generator):
    """What one BSDF-sampled ray from each point of ``x`` hits: the glossy lobe with its share of the point's
    albedo (luminance of Glossy Color over it plus the diffuse albedo), the cosine-weighted diffuse lobe otherwise.
    Every point draws all its numbers, so how many take the glossy lobe does not change the other points' draws."""
    if not scene.materials.glossy:
        return diffuse_bounce(scene, tracer, x, rng)[0]
    u = rng.random((5, len(x)))
    dirs, _ = cosine_hemisphere(u[0], u[1], x.shading_normal)
    lobe = GlossyLobe.of(x)
    gloss = luminance(lobe.color)
    share = gloss / np.maximum(gloss + luminance(x.albedo), 1e-300)
    shiny = np.nonzero(u[2] < share)[0]
    dirs[shiny] = lobe.sample(u[3, shiny], u[4, shiny], shiny)[0]
    return bounce(scene, tracer, x, dirs)[0]


def candidates(scene, tracer, count: int, rng: np.random.Generator, passes: int = 8):
    """(positions, normals) of ``count`` points seen from camera-path ends (sec. 3.1), the same number of camera
    samples in every pixel (or in a random subset of the pixels, below); normals face the point that found them.
    Rays that find nothing (an open scene) are made up by further passes over the image, at most ``passes`` in all.
    Each batch of pixels draws from a generator of its own (seeded from ``rng`` and its place), so what one batch
    found (a moving object's metal) does not change the numbers of the next.

    With fewer candidates to find than pixels, a pass takes the pixels in a random order and stops when it has
    found enough: a random subset of the image. Taking the first ``count`` found in pixel order had kept the top
    rows only (the Cornell box's default, 40,960 of 65,536 pixels: at least its top 62 %), and a 1080p frame had
    traced a path in each of its 2 M pixels for 40,960 candidates."""
    cam = scene.camera
    pixels = cam.width * cam.height
    found_p, found_n, found = [], [], 0
    seed = int(rng.integers(1 << 63))
    for number in range(passes):
        spp = max(1, math.ceil((count - found) / pixels))
        order = rng.permutation(pixels) if spp == 1 else np.arange(pixels)
        step = max(1, PIXELS_PER_BATCH // spp)
        for lo in range(0, pixels, step):
            if spp == 1 and found >= count:
                break
            batch = np.random.default_rng([seed, number, lo])
            x = GBuffer.build(scene, tracer, order[lo:lo + step], spp, batch).surface
            y = _bsdf_bounce(scene, tracer, x, batch)
            for _ in range(SPECULAR_EXTENSION):  # Fig. 6b: on metal, the camera path goes on
                metal = (largest(y.albedo) == 0.0) & y.glossy
                if not metal.any():
                    break
                y = Surface.concat([y.take(np.nonzero(~metal)[0]),
                                    _bsdf_bounce(scene, tracer, y.take(np.nonzero(metal)[0]), batch)])
            y = y.take(np.nonzero(largest(y.albedo) > 0.0)[0])  # lights hold diffusely reflected light only
            found_p.append(y.position)
            found_n.append(y.smooth_normal)
            found += len(y)
        if found >= count or found == 0:
            break
    return np.concatenate(found_p)[:count], np.concatenate(found_n)[:count]


def view_candidates(context, count: int, seed: int):
    """``candidates`` for a frame: in a sequence, of the scene without the objects that move in it
    (``MethodContext.still``), so that an object moving through the view does not move lights all over the room
    (drawn from the whole scene, 14 % of the candidates change each frame of the moving block, and the lights with
    them: ``bench/sequence_temporal.py``). The light those
    objects reflect is found by extending the camera paths that meet them, which no light covers (eq. 6-9). A
    still scene in which fewer than half the candidates are found (a camera that sees mostly what moves) gives way
    to the whole scene."""
    still = context.still() if context.still is not None else None
    if still is not None:
        scene, tracer = still
        found = candidates(scene, tracer, count, np.random.default_rng(seed))
        context.tracer.count(tracer.rays_traced)
        if 2 * len(found[0]) >= count:
            return found
    return candidates(context.scene, context.tracer, count, np.random.default_rng(seed))


class Catchment(NamedTuple):
    """What ``catchment`` measures of each light's share s_j of the surface."""
    area: np.ndarray  # (N,) A_j = integral s_j dA
    centre: np.ndarray  # (N,3) integral s_j y dA / A_j (the light's position where A_j = 0)
    flat: np.ndarray  # (N,) bool: every point of the disc within its reach found the surface (``fit_slopes``)


def catchment(lights, scene, tracer, per_light: int, rng: np.random.Generator) -> Catchment:
    """A_j, the surface area of each light's share (``photon_lights``), with its centre and whether the surface is
    the whole disc (``Catchment``): ``per_light`` stratified points of
    the disc of radius r_j in the light's tangent plane, dropped onto the surface along -n_j by a ray from
    ``DROP`` r_j above to as far below, each standing for pi r_j^2 / per_light of the disc divided by the cosine
    between the surface and the disc; the sum of their shares s_j. Exact on flat surfaces; points past an edge
    find no surface, and points on surfaces without a diffuse colour (pure metal), add nothing. The short drop
    keeps other surfaces near the light (a shelf above a floor) from hiding the light's own.

    A light on a thin part (a window frame, a chair leg) has its area decided by the few points that land on it:
    one point of 32, or one at the rim of the disc, gives an area 30 or 1000 times too small or large and, as
    L_j = I_j / A_j, a light as much too bright or dark (the living room had a light 20000 times the median
    radiance, a square blotch after the filter). Lights whose share is found by fewer than a quarter of their
    points are measured again with ``REFINE`` times as many."""
    found, missed, sums = _dropped_shares(lights, np.arange(len(lights)), scene, tracer, per_light, rng)
    few = np.nonzero(found < per_light / 4)[0]
    if len(few):
        sums[few] = _dropped_shares(lights, few, scene, tracer, per_light * REFINE, rng)[2]
    area = sums[:, 0]
    offset = np.where(area[:, None] > 0.0, sums[:, 1:] / np.maximum(area, 1e-300)[:, None], 0.0)
    return Catchment(area, lights.position + offset, missed == 0)


def open_reach(position, normal, radius, tracer) -> np.ndarray:
    """(N, SECTORS) how far each light's support reaches from its centre in each sector of its disc: the nearest
    hit of two rays per sector (at a quarter of its width either side of its middle) along the light's plane,
    ``LIFT`` r above it, at most r. A wall standing on a floor, a door leaf, a sofa's side cut a floor light's
    disc where they stand, so the light neither takes the photons of the floor behind them (another room, the
    patch of sun under a table) nor lends its light there: photon splitting, the catchment and the gather all test
    it (``photon_lights._covering``). Without it, 5-10 % of the living room's photon light would reach its lights
    across such an occluder."""
    count = len(radius)
    if count == 0:
        return np.zeros((0, SECTORS))
    angle = sector_angle((np.arange(2 * SECTORS) + 0.5) / 2.0)  # two per sector
    t, b = orthonormal_basis(normal)
    d = np.cos(angle)[None, :, None] * t[:, None, :] + np.sin(angle)[None, :, None] * b[:, None, :]
    origin = tracer.offset_origin(position + (LIFT * radius)[:, None] * normal, normal)
    hits = tracer.intersect(np.repeat(origin, 2 * SECTORS, axis=0), d.reshape(-1, 3),
                            tmax=np.repeat(radius, 2 * SECTORS))
    far = np.where(hits.hit, hits.t, np.repeat(radius, 2 * SECTORS)).reshape(count, SECTORS, 2)
    return np.minimum(far.min(axis=2), radius[:, None])


def _dropped_shares(lights, which, scene, tracer, per_light, rng):
    """(points that found a share, points within the disc's reach that found no surface, (L, 4) sums of s_j dA and
    s_j (y - y_j) dA) of the lights ``which``, as ``catchment`` describes."""
    found, missed, sums = np.zeros(len(which)), np.zeros(len(which)), np.zeros((len(which), 4))
    if len(which) == 0 or per_light <= 0:
        return found, missed, sums
    step = max(1, POINTS_PER_BATCH // per_light)
    for lo in range(0, len(which), step):
        own = np.arange(lo, min(len(which), lo + step))
        u, v = stratified_2d(len(own), per_light, rng)
        dx, dy = concentric_disk(u.ravel(), v.ravel())
        k = np.repeat(own, per_light)  # position in ``which``
        j = which[k]
        t, b = orthonormal_basis(lights.normal[j])
        r, n = lights.radius[j], lights.normal[j]
        on_plane = lights.position[j] + (dx * r)[:, None] * t + (dy * r)[:, None] * b
        start = tracer.offset_origin(on_plane + (DROP * r)[:, None] * n, n)  # above float32 noise far away
        hits = tracer.intersect(start, -n, tmax=dot(start - on_plane, n) + DROP * r)
        rows = np.nonzero(hits.hit)[0]
        y = shade(scene, -n, hits, rows)
        slope = np.abs(dot(y.geometric_normal, n[rows]))
        lids = lid_heights(tracer, y.position, y.geometric_normal, LID * float(r.max()))
        mine = lights.share_of(y.position, y.shading_normal, j[rows], lids) * (largest(y.albedo) > 0.0)
        patch = np.pi * r[rows] ** 2 / per_light / np.maximum(slope, 1e-3)  # the surface a point stands for
        found += np.bincount(k[rows], mine > 0.0, len(which))
        # the points within the disc's reach that found no surface (an edge, a curve): the disc is not flat
        sector = sector_of(dx, dy).astype(np.int64)
        reach = 1.0 if lights.reach is None else lights.reach[j, sector] / r
        missed += np.bincount(k[~hits.hit & (dx * dx + dy * dy <= reach * reach)], minlength=len(which))
        off = y.position - lights.position[j[rows]]
        for column, term in enumerate((mine, *(mine * off.T))):
            sums[:, column] += np.bincount(k[rows], term * patch, len(which))
    return found, missed, sums


def start(context, settings) -> PlacedFromPaths:
    return PlacedFromPaths()


def advance(state: PlacedFromPaths, context, settings, motion):
    return state.advance(place, context, settings, motion)


def place(context, settings, state: PlacedFromPaths | None = None, motion=None):
    """(lights, info): sec. 3's placement. The photons' light paths do not depend on the lights, so they are traced
    on a thread of their own (``photon_batches``), with random numbers of their own, while the candidates are
    found and thinned, and on as many threads as the tracer has after that: at most ``AHEAD`` batches ahead of
    their splitting. A sequence's kept paths are followed first, alone, so that the rays the tracer counts
    meanwhile are theirs (``light_path_rays``, the paper's Fig. 7 count)."""
    s = settings.vbnl
    marks = {"start": time.perf_counter()}
    seed = tuple(int(x) for x in context.rng.integers(1 << 63, size=2))
    own = replace(context, rng=np.random.default_rng(seed))
    tracing = ThreadPoolExecutor(context.tracer.threads)
    lanes = threading.Semaphore(1)  # one tracing thread while this one finds and thins the candidates
    try:
        if state is None:
            aimed = aimed_lights(context.scene, context.lights, s.aimed_caustics) \
                if s.sampling.caustic_photons and s.aimed_caustics > 0.0 and context.max_bounces > 1 else None
            batches = photon_batches(context, s.photons, seed, tracing, lanes, aimed, s.aimed_caustics)
        else:
            traced = follow(state.paths, own, motion, 0, settings.path_reuse, settings.path_threshold,
                            paths=s.photons)
            marks["light_paths"] = time.perf_counter()
        view = context.camera_rng or context.rng  # the same in every frame of a sequence: steady lights
        position, normal = view_candidates(context, s.candidates * settings.vpls, view.integers(1 << 63))
        marks["candidates"] = time.perf_counter()
        kept = eliminate(position, settings.vpls, view, mode=s.elimination, local=s.local,
                         checkpoint=context.tracer.checkpoint)
        at, facing, radius = position[kept.keep], normal[kept.keep], ALPHA * kept.r_max
        lights = PhotonLights(at, facing, radius, np.zeros((len(kept.keep), 3)),
                              reach=open_reach(at, facing, radius, context.tracer))
        marks["elimination"] = time.perf_counter()
        share = catchment(lights, context.scene, context.tracer, s.area_samples,
                          np.random.default_rng(view.integers(1 << 63)))
        lights.catchment, lights.centre = share.area, share.centre
        marks["catchment"] = time.perf_counter()
        if context.tracer.threads > 1:  # the splitting waits for the photons: trace on every thread
            lanes.release(context.tracer.threads - 1)
        bounces = max(context.max_bounces, 1)
        if state is None:  # intensities divided by the number of paths
            traced = s.photons if len(lights) else 0
            split = split_photons(lights, batches if traced else (), bounces, context.tracer)
            by_bounce, halves = (a / max(traced, 1) for a in split)
        else:  # the kept photons, intensities already divided by the number of paths
            photons = state.paths.lights()
            by_bounce, halves = split_photons(lights, (photons.take(slice(first, first + POINTS_PER_BATCH))
                                                       for first in range(0, len(photons), POINTS_PER_BATCH)),
                                              bounces, context.tracer)
    finally:
        lanes.release(context.tracer.threads)  # no job waits for a lane that is never freed
        tracing.shutdown(cancel_futures=True)
    lights.by_bounce = np.cumsum(by_bounce[:, :bounces], axis=1)
    lights.intensity = lights.by_bounce[:, -1]
    if state is None:  # a sequence's photons continue paths whose past is not kept: no caustic tells apart there
        lights.caustic = by_bounce[:, bounces]
    lights.slope = fit_slopes(lights.position, lights.normal, lights.radius, lights.reach, share.flat,
                              luminance(lights.radiance), halves)
    marks["photon_splitting"] = time.perf_counter()
    stages = list(marks)
    seconds = {b: marks[b] - marks[a] for a, b in zip(stages, stages[1:])}
    info = {"vpls": len(lights), "candidates": len(position), "light_paths": traced, "seconds": seconds,
            "covered_share": float((lights.intensity.sum(axis=1) > 0).mean()) if len(lights) else 0.0}
    if state is not None:
        info["light_path_rays"] = state.paths.rays_last_frame
    return lights, info


def photon_batches(context, paths: int, seed: tuple, executor, lanes: threading.Semaphore | None = None,
                   aimed: AimedLights | None = None, share: float = 0.0):
    """The photons (light-path vertices) of ``paths`` light paths in batches of ``PATHS_PER_BATCH`` paths, in
    order, traced on the threads of ``executor`` at most ``AHEAD`` batches ahead of the caller; with ``lanes``, on
    only as many threads at once as it lets through. Each batch draws from a generator of its own, seeded by
    ``seed`` and its first path: the photons do not depend on which thread traced them, or on how many there are.
    With ``aimed`` lights (``caustic_photons.aimed_lights``), the caustic photons of ``share`` times as many paths
    of theirs follow, in place of the distant lights' own, weighted so that they too are divided by ``paths``."""
    caustics = distant_caustics(context.lights, aimed)
    starts = range(0, paths, PATHS_PER_BATCH)
    jobs = [partial(_photons, context, seed, first, min(PATHS_PER_BATCH, paths - first), lanes, caustics)
            for first in starts]
    if aimed is not None:
        count = max(1, int(paths * share))
        jobs += [partial(_caustic_photons, context, aimed, seed, first, min(PATHS_PER_BATCH, count - first), lanes,
                         paths / count) for first in range(0, count, PATHS_PER_BATCH)]
    return _ahead(jobs, executor, AHEAD)


def _photons(context, seed: tuple, first: int, paths: int, lanes=None, caustics=None):
    """The photons of ``paths`` light paths, the first numbered ``first``; ``caustics`` as ``trace_paths``'."""
    with lanes or nullcontext():
        return trace_paths(context.scene, context.tracer, context.lights, paths,
                           np.random.default_rng([*seed, first]), context.max_bounces, first_path=first,
                           caustics=caustics)


def _caustic_photons(context, aimed: AimedLights, seed: tuple, first: int, paths: int, lanes=None, weight=1.0):
    """The caustic photons of ``paths`` aimed light paths, the first numbered ``first``, times ``weight``."""
    with lanes or nullcontext():
        return trace_caustic_photons(context.scene, context.tracer, aimed, paths,
                                     np.random.default_rng([*seed, first, 1]), first_path=first).scaled(weight)


def _ahead(jobs, executor, depth: int):
    """The results of ``jobs`` in order, each run on ``executor`` while at most ``depth`` - 1 results wait to be
    taken (the first ``depth`` start at once)."""
    jobs = iter(jobs)
    pending = deque(executor.submit(job) for job in islice(jobs, depth))

    def results():
        while pending:
            done = pending.popleft().result()
            pending.extend(executor.submit(job) for job in islice(jobs, 1))
            yield done
    return results()


def split_photons(lights, batches, bounces: int, tracer) -> tuple[np.ndarray, np.ndarray]:
    """Photon splitting (sec. 3.3): the intensity of the photons of ``batches`` shared among the lights covering
    them (not those under a lid, ``photon_lights.LID``), split over the tracer's threads a batch at a time (or,
    with many lights, as many batches at a time as make ``Splitting.points`` photons); a ``checkpoint`` of the
    tracer after each batch. Returns (N, bounces + 1, 3) the intensity kept apart by bounce, then the caustic
    photons' white-receiver intensity (``VirtualLights.caustic``), and (N, 2, 4) their luminance and its first
    moment (sum of k_j I_p p) weighted by the lights' kernels, of the photons of even and of odd light paths apart
    (``fit_slopes``)."""
    reach = LID * float(lights.radius.max()) if len(lights) else 0.0
    with ThreadPoolExecutor(tracer.threads) as pool:
        splitting = Splitting(lights, bounces + 1, 3, pool, tracer.threads, raw_groups=2, raw_channels=4)
        held = []
        for photons in chain(batches, [None]):
            if photons is not None:
                held.append(photons)
            if held and (photons is None or sum(map(len, held)) >= splitting.points):
                photons = VirtualLights.concat(held)
                held = []
                points, normals, values, groups, raw, raw_groups = _split_rows(photons, bounces)
                splitting.add(points, normals, values, groups, lid_heights(tracer, points, normals, reach), raw,
                              raw_groups)
            tracer.checkpoint()
    return splitting.total(), splitting.raw_total()


def _split_rows(photons, bounces: int):
    """(points, normals, values, groups, raw values, raw groups) that photon splitting shares: every photon that
    holds light by its bounce, and those that hold a caustic's light (``VirtualLights.caustic``) once more, their
    white-receiver intensity in the group after the last bounce (an aimed caustic photon holds only that); the raw
    values each photon's luminance and its first moment, in the group of the parity of its light path
    (``fit_slopes``), zero for the caustic copies, which the slopes do not weigh."""
    caustic = photons.take(np.nonzero(photons.caustic.any(axis=1))[0])
    lit = photons.intensity.any(axis=1)
    held = photons if lit.all() else photons.take(np.nonzero(lit)[0])
    light = luminance(held.intensity)[:, None]
    return (np.concatenate([held.position, caustic.position]), np.concatenate([held.normal, caustic.normal]),
            np.concatenate([held.intensity, caustic.caustic]),
            np.concatenate([held.bounce - 1, np.full(len(caustic), bounces)]),
            np.concatenate([np.concatenate([light, light * held.position], axis=1), np.zeros((len(caustic), 4))]),
            np.concatenate([held.path % 2, np.zeros(len(caustic), np.int64)]))


def gather_samples(settings, camera_samples: int) -> int:
    """Sample pairs per pixel the gather takes: the setting, or one per camera sample where it is 0."""
    return settings.vbnl.sampling.samples or camera_samples


def frame_settings(settings, camera_samples: int):
    """``settings`` with the automatic light paths of a frame of ``camera_samples`` in all made a number
    (``VBNLSettings.light_paths``)."""
    return replace(settings, vbnl=replace(settings.vbnl, photons=settings.vbnl.light_paths(camera_samples)))


def gather(surface, lights, context, settings, rng, glossy=None, pixel=None):
    return virtual_light_sampling.gather(surface, lights, context.scene, context.tracer, context.lights, rng,
                                         settings.vbnl.sampling, context.max_bounces, glossy, pixel)


# a sequence's candidates come from its still scene: a bake finds what moves before its first frame
METHOD = Method(
    "vbnl", "Virtual Blue Noise Lighting", "Li et al. 2022: lights placed from the camera in a blue-noise pattern, "
                                           "lit by photon splitting, sampled with MIS and path extension",
    place, VBNLSettings, start=start, advance=advance, gather=gather, gather_samples=gather_samples,
    frame_settings=frame_settings, uses_still=True, reuses_light_paths=True, budget="samples")
