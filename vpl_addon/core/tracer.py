"""The one ray tracer: embree's BVH queried in large batches, split over all cores.

``embreex`` releases the GIL inside ``run``, so chunks of a batch run concurrently on a thread pool. Embree works
in float32 on coordinates relative to the centre of the scene's bounding box (callers keep world coordinates in
float64): a room 100 km from the origin is traced as precisely as one at the origin. Origins are pushed off the
surface they leave by ``offset_origin`` (Waechter and Binder, "A Fast and Robust Method for Avoiding
Self-Intersection", Ray Tracing Gems ch. 6): a few float ULPs along the geometric normal, with the absolute fallback
near zero scaled to the scene's extent so tiny and huge scenes behave alike.

Alpha cut-outs and thin glass (``materials.cutouts``, handed in as ``cutouts``): a hit on a triangle with holes
or glass is kept with the probability of its opacity; a ray that goes on is traced again from just past the
surface, at most ``CUTOUT_LAYERS`` times (Cycles' default Transparent bounce limit is 8; the last layer found then
stops the ray). An occlusion query asks two BVHs of the scene's parts first (``_parts``): a ray that a triangle
without holes blocks is blocked whatever the cut-outs let through, and of the rest, only those a cut-out triangle
blocks are traced again, closest hit by closest hit, through the whole scene. (With one BVH every blocked ray would be
traced again: 99.7 % of the living room's shadow rays toward its sky, whose windows are glass.) Rays asked to
(``tinted``) carry the colour of the coloured glass they cross (``Hits.tint``).
"""
from __future__ import annotations

import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .compiled import kernel
from .rows import concat_fields, take_fields

ULP_OFFSET = 16.0  # float32 steps along the normal; Waechter-Binder's 256 moves a point 2 m at 1e5 m from 0
CHUNK = 1 << 16  # rays per embree call: large enough to amortise Python, small enough to share across threads
FAR = 1e30
CUTOUT_LAYERS = 16
# Benchmarks only: when set, called as OCCLUSION_RECORDER(origins, dirs, tmax) with every occlusion batch, so
# bench/ can replay the engine's own shadow rays through raw embreex. None (always, in renders): no cost.
OCCLUSION_RECORDER = None


@dataclass
class Hits:
    prim: np.ndarray  # (N,) int32 triangle index, -1 for a miss
    t: np.ndarray  # (N,) float64 distance along the (unit) direction, inf for a miss
    u: np.ndarray  # (N,) barycentric weight of corner 1
    v: np.ndarray  # (N,) barycentric weight of corner 2
    tint: np.ndarray | None = None  # (N,3) what coloured glass on the way leaves of the light (``tinted``), or None

    @property
    def hit(self) -> np.ndarray:
        return self.prim >= 0

    def take(self, index) -> "Hits":
        return take_fields(self, index)

    @staticmethod
    def concat(parts: list["Hits"]) -> "Hits":
        return concat_fields(Hits, parts)


class Tracer:
    """Closest-hit and occlusion queries against the scene's triangles."""

    def __init__(self, triangles: np.ndarray, threads: int | None = None, cutouts=None, seed: int = 0,
                 center: np.ndarray | None = None):
        """``center``: the point embree's float32 coordinates are taken from (default: the middle of the
        triangles' bounds). A tracer built again for a changed scene (a sequence's next frame, the scene without
        what moves) given the old one's traces what did not change to the same bits."""
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        if center is not None:
            self.center = np.array(center, np.float64)
        else:
            self.center = 0.5 * (tri.min(axis=(0, 1)) + tri.max(axis=(0, 1))) if len(tri) else np.zeros(3)
        tri = np.ascontiguousarray(tri - self.center, dtype=np.float32)
        self.triangle_count = len(tri)
        self.threads = max(1, threads or os.cpu_count() or 1)
        self.rays_traced = 0  # counted under ``_counting``: the render's blocks trace on two threads at once
        self.embree_seconds = 0.0  # seconds callers waited on embree, summed over their threads (``_counting``)
        self._counting = threading.Lock()
        self._waited = threading.local()  # the calling thread's own share of ``embree_seconds``
        extent = float(np.abs(tri).max()) if len(tri) else 1.0
        self.extent = extent if extent > 0.0 else 1.0
        self.cutouts = cutouts  # materials.cutouts.Cutouts of these triangles, or None (no holes)
        self._seed = int(seed)
        self._triangles, self._normals = tri, None
        self._scene, self._mesh = _bvh(tri)
        self._split, self._splitting = None, threading.Lock()  # ``_parts``: (cut-out mask, opaque BVH, cut-out BVH)
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None

    def checkpoint(self) -> None:
        """Nothing: a place where long work without rays (sample elimination, photon splitting) may be stopped.
        An interruptible tracer (``progressive.Interruptible``) checks its stop flag on every call of a tracer
        method, this one included."""

    def count(self, rays: int) -> None:
        """Count ``rays`` traced for this tracer's frame by another tracer (of part of the same scene)."""
        with self._counting:
            self.rays_traced += int(rays)

    def close(self):
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def _run(self, origins, dirs, tfar, query, bvh=None):
        o = np.ascontiguousarray(np.asarray(origins, np.float64) - self.center, dtype=np.float32)
        d = np.ascontiguousarray(dirs, dtype=np.float32)
        tf = np.ascontiguousarray(np.minimum(tfar, FAR), dtype=np.float32)
        return self._run32(o, d, tf, query, bvh)

    def waited(self) -> float:
        """Seconds the calling thread has waited on embree through this tracer: the part of a stage's time that
        is the ray tracer's (``bench/profile.py``)."""
        return getattr(self._waited, "seconds", 0.0)

    def _run32(self, o, d, tf, query, bvh=None):
        """embree's answers for rays in its own terms: float32, origins relative to ``center``; against ``bvh``
        (one of ``_parts``) or the whole scene. The call's time is counted in ``embree_seconds`` and ``waited``."""
        t0 = time.perf_counter()
        parts = self._traced(o, d, tf, query, bvh)
        seconds = time.perf_counter() - t0
        self._waited.seconds = self.waited() + seconds
        with self._counting:
            self.rays_traced += len(o)
            self.embree_seconds += seconds
        return parts

    def _traced(self, o, d, tf, query, bvh):
        """``_run32``'s answers: the rays in chunks, on the tracer's threads when there are several chunks."""
        n = len(o)
        output = 1 if query == "INTERSECT" else None
        bvh = self._scene if bvh is None else bvh

        def job(lo):
            hi = min(lo + CHUNK, n)
            return bvh.run(o[lo:hi], d[lo:hi], dists=tf[lo:hi].copy(), query=query, output=output)

        starts = range(0, n, CHUNK)
        parts = list(self._pool.map(job, starts)) if self._pool and n > CHUNK else [job(s) for s in starts]
        return parts

    def intersect(self, origins: np.ndarray, dirs: np.ndarray, tmax=FAR, tinted: bool = False) -> Hits:
        """Closest hits of rays with unit directions, up to distance tmax (scalar or per ray), through the holes and
        panes of ``cutouts``. ``tinted``: the rays carry the colour of the coloured glass they cross
        (``Hits.tint``; ``Cutouts.passes``) rather than crossing it as grey."""
        return self.intersect_through(origins, dirs, tmax, tinted)[0]

    def intersect_through(self, origins: np.ndarray, dirs: np.ndarray, tmax=FAR,
                          tinted: bool = False) -> tuple[Hits, np.ndarray]:
        """(``intersect``'s hits, (N,) bool: which rays went through glass on the way)."""
        hits, crossed, _ = self._layers(origins, dirs, tmax, bend=False, tinted=tinted)
        return hits, crossed

    def intersect_bent(self, origins: np.ndarray, dirs: np.ndarray, tmax=FAR) -> tuple[Hits, np.ndarray, np.ndarray]:
        """``intersect`` (``tinted``) for rays that refract at glass as Cycles' camera rays do (``Cutouts.passes``
        with ``bend``): their hits, ``t`` the length of the whole bent path, (N,3) the unit direction each ray has
        at its hit (or leaves the scene with), and (N,) bool which rays crossed glass."""
        hits, crossed, heading = self._layers(origins, dirs, tmax, bend=True, tinted=True)
        return hits, heading, crossed

    def intersect_first(self, origins: np.ndarray, dirs: np.ndarray, tmax=FAR) -> Hits:
        """``intersect`` that stops at glass (``Cutouts.passes`` with ``solid_glass``): the first surface each
        ray meets past the holes, as Cycles' data passes see it."""
        return self._layers(origins, dirs, tmax, bend=False, solid_glass=True)[0]

    def _layers(self, origins, dirs, tmax, bend: bool, tinted: bool = False,
                solid_glass: bool = False) -> tuple[Hits, np.ndarray, np.ndarray]:
        """Closest hits through the holes and panes of ``cutouts`` (``Cutouts.passes``' modes), which rays went
        through glass, and the directions the rays end with (``dirs`` itself unless ``bend``). Only the rays that
        meet a cut-out triangle carry the state of their last segment (its start, direction and the path's length
        there)."""
        hits = self._closest(origins, dirs, tmax)
        crossed = np.zeros(len(origins), bool)
        if self.cutouts is None:
            return hits, crossed, dirs
        todo = np.nonzero(hits.hit)[0]
        todo = todo[self.cutouts.prims[hits.prim[todo]]]
        if not len(todo):
            return hits, crossed, dirs
        if tinted and self.cutouts.weighs:
            hits.tint = np.ones((len(origins), 3))
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), (len(origins),))
        rng = self._stream(origins, dirs)
        heading = np.array(dirs, np.float64) if bend else dirs
        base, d = np.asarray(origins[todo], np.float64), np.asarray(dirs[todo], np.float64)  # the last segments
        walked = np.zeros(len(todo))  # the path's length where each starts
        for layer in range(CUTOUT_LAYERS):
            if layer:
                keep = self.cutouts.prims[hits.prim[todo]]
                todo, base, d, walked = todo[keep], base[keep], d[keep], walked[keep]
                if not len(todo):
                    break
            ng = self._face_normals()[hits.prim[todo]]
            on, glass, onward, weight = self.cutouts.passes(hits.prim[todo], hits.u[todo], hits.v[todo], d, ng, rng,
                                                            bend, tinted, solid_glass)
            crossed[todo[glass]] = True
            if weight is not None:
                hits.tint[todo] *= weight
            todo, base, d, walked, ng, onward = todo[on], base[on], d[on], walked[on], ng[on], onward[on]
            if not len(todo):
                break
            point = base + d * (hits.t[todo] - walked)[:, None]
            through = np.where((np.einsum("ij,ij->i", ng, onward) >= 0.0)[:, None], ng, -ng)  # the side it goes to
            base = self.offset_origin(point, through)
            walked = hits.t[todo] + np.einsum("ij,ij->i", base - point, d)  # where the new segment starts
            d = onward
            if bend:
                heading[todo] = onward
            beyond = self._closest(base, d, tmax[todo] - walked)
            hits.prim[todo], hits.u[todo], hits.v[todo] = beyond.prim, beyond.u, beyond.v
            hits.t[todo] = walked + beyond.t  # inf for rays that now miss
            keep = beyond.hit
            todo, base, d, walked = todo[keep], base[keep], d[keep], walked[keep]
        return hits, crossed, heading

    def _stream(self, origins, dirs) -> np.random.Generator:
        """Random numbers for the cut-out decisions of one batch, seeded by the tracer's seed and the batch's
        contents: the same rays draw the same numbers whichever thread traces them first, so a seed gives one
        image."""
        key = np.array([np.sum(origins, dtype=np.float64), np.sum(dirs, dtype=np.float64)]).view(np.uint64)
        return np.random.default_rng([self._seed, len(origins), *key.tolist()])

    def _face_normals(self) -> np.ndarray:
        if self._normals is None:
            tri = self._triangles.astype(np.float64)
            ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            self._normals = ng / np.maximum(np.linalg.norm(ng, axis=1, keepdims=True), 1e-300)
        return self._normals

    def _closest(self, origins: np.ndarray, dirs: np.ndarray, tmax=FAR) -> Hits:
        n = len(origins)
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,))
        if self._scene is None or n == 0:
            return Hits(np.full(n, -1, np.int32), np.full(n, np.inf), np.zeros(n), np.zeros(n))
        parts = self._run(origins, dirs, tmax, "INTERSECT")
        prim = np.concatenate([p["primID"] for p in parts]).astype(np.int32)
        t = np.concatenate([p["tfar"] for p in parts]).astype(np.float64)
        u = np.concatenate([p["u"] for p in parts]).astype(np.float64)
        v = np.concatenate([p["v"] for p in parts]).astype(np.float64)
        miss = prim < 0
        t[miss] = np.inf
        u[miss] = 0.0
        v[miss] = 0.0
        return Hits(prim, t, u, v)

    def occluded(self, origins: np.ndarray, dirs: np.ndarray, tmax) -> np.ndarray:
        """True where something lies along the ray before tmax."""
        return self.occluded_through(origins, dirs, tmax)[0]

    def occluded_through(self, origins: np.ndarray, dirs: np.ndarray, tmax,
                         tinted: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(``occluded``, (N,) bool: which unblocked rays went through glass, and with ``tinted`` (N,3) what
        coloured glass leaves of each unblocked ray's light, or None where no coloured glass is met)."""
        n = len(origins)
        if self._scene is None or n == 0:
            return np.zeros(n, bool), np.zeros(n, bool), None
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,))
        if OCCLUSION_RECORDER is not None:
            OCCLUSION_RECORDER(origins, dirs, tmax)
        crossed, tint = np.zeros(n, bool), None
        if self.cutouts is None:
            return np.concatenate(self._run(origins, dirs, tmax, "OCCLUDED")) >= 0, crossed, tint
        opaque, holed = self._parts()
        blocked = np.zeros(n, bool) if opaque is None else \
            np.concatenate(self._run(origins, dirs, tmax, "OCCLUDED", opaque)) >= 0
        rows = np.nonzero(~blocked)[0]  # blocked by a hole or a pane? the closest hits through them tell
        if holed is not None and len(rows):
            rows = rows[np.concatenate(self._run(origins[rows], dirs[rows], tmax[rows], "OCCLUDED", holed)) >= 0]
            hits, through = self.intersect_through(origins[rows], dirs[rows], tmax[rows], tinted)
            blocked[rows], crossed[rows] = hits.hit, through & ~hits.hit
            if hits.tint is not None:
                tint = np.ones((n, 3))
                tint[rows] = hits.tint
        return blocked, crossed, tint

    def _parts(self) -> tuple:
        """(BVH of the triangles without holes or glass, BVH of those with them), each None where there are
        none; built at the first occlusion query with ``cutouts`` and again when they change (a sequence's frame
        may change alpha without the triangles). The cut-outs' own mask, seen before, is not compared again (a flag
        per triangle at every occlusion query)."""
        prims = self.cutouts.prims
        with self._splitting:
            if self._split is None or (self._split[0] is not prims and not np.array_equal(self._split[0], prims)):
                self._split = (prims, _bvh(self._triangles[~prims]), _bvh(self._triangles[prims]))
            elif self._split[0] is not prims:  # another Cutouts with the same mask: its BVHs serve it
                self._split = (prims, *self._split[1:])
            return self._split[1][0], self._split[2][0]

    def offset_origin(self, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """Move points p off their surface along the (geometric) normal n, toward the side n points to: by
        ULP_OFFSET float32 steps of the point's (centred) coordinates, and at least extent / 65536 (near the
        centre a few steps of a tiny coordinate are less than embree's error on the triangle's larger ones)."""
        p = np.asarray(p, np.float64)
        out = np.empty(p.shape)
        n = np.ascontiguousarray(np.broadcast_to(np.asarray(n, np.float32), p.shape))
        _offset(np.ascontiguousarray(p).reshape(-1, 3), n.reshape(-1, 3), self.center,
                np.float32(self.extent / 65536.0), out.reshape(-1, 3))
        return out

    def visible(self, p: np.ndarray, n: np.ndarray, dirs: np.ndarray, dist: np.ndarray,
                target_normal: np.ndarray | None = None, origin: np.ndarray | None = None) -> np.ndarray:
        """``visible_through``'s visibility alone."""
        return self.visible_through(p, n, dirs, dist, target_normal, origin)[0]

    def visible_through(self, p: np.ndarray, n: np.ndarray, dirs: np.ndarray, dist: np.ndarray,
                        target_normal: np.ndarray | None = None, origin: np.ndarray | None = None,
                        at: np.ndarray | None = None, tinted: bool = False
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Visibility from surface points p (geometric normal n) along unit dirs to a point at distance dist.

        The origin is offset to the side of n that dirs leaves through; when the target lies on a surface too,
        its normal shortens the segment by the same robust margin so the target does not occlude itself (a zero
        target normal means the target is not on geometry). ``origin``: the offset origins when the caller has
        them already (many rays leaving one point through the same side, ``offset_origin(p, n)``). ``at``: p and
        ``origin`` (then required) hold a row per point, and ray i leaves point at[i] (many rays from one point
        need no copies of it). Returns (visible, whether the visible ray went through glass, and with ``tinted``
        what coloured glass leaves of its light, ``occluded_through``).
        """
        count = len(dirs)
        if self._scene is None or count == 0:
            return np.ones(count, bool), np.zeros(count, bool), None
        if origin is None:
            side = np.where((np.einsum("ij,ij->i", n, dirs) >= 0.0)[:, None], n, -n)
            origin = self.offset_origin(p, side)
        at = np.arange(count) if at is None else at
        target = np.empty((0, 3))
        if target_normal is not None:
            t_side = np.where((np.einsum("ij,ij->i", target_normal, dirs) <= 0.0)[:, None],
                              target_normal, -target_normal)
            target = self.offset_origin(p[at] + dirs * np.where(np.isfinite(dist), dist, 0.0)[:, None], t_side)
        if self.cutouts is None and OCCLUSION_RECORDER is None:  # the rays made in embree's terms: no copies
            o, d, t = np.empty((count, 3), np.float32), np.empty((count, 3), np.float32), np.empty(count, np.float32)
            _segments(p, at, dirs, dist, origin, target, self.center, o, d, t)
            return np.concatenate(self._run32(o, d, t, "OCCLUDED")) < 0, np.zeros(count, bool), None
        o, d, t = np.empty((count, 3)), np.empty((count, 3)), np.empty(count)
        _segments(p, at, dirs, dist, origin, target, np.zeros(3), o, d, t)
        blocked, crossed, tint = self.occluded_through(o, d, t, tinted)
        return ~blocked, crossed, tint


def _bvh(triangles: np.ndarray) -> tuple:
    """(embree scene, its mesh) of (T,3,3) float32 triangles, or (None, None) for none."""
    if not len(triangles):
        return None, None
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    scene = rtcore_scene.EmbreeScene()
    return scene, TriangleMesh(scene, np.ascontiguousarray(triangles))


@kernel
def _segments(p, at, dirs, dist, origin, target, shift, o, d, t):
    """The shadow rays of ``visible_through``, written as (o - ``shift``, d, t) in the arrays' precision: ray i
    from ``origin[at[i]]`` toward the point at ``dist[i]`` along ``dirs[i]`` from p[at[i]] (or ``target[i]`` if
    given: that point moved off its own surface), stopping just short of it; a ray to an infinite distance keeps
    its direction and goes to ``FAR``."""
    for i in range(len(dirs)):
        j = at[i]
        o[i, 0], o[i, 1], o[i, 2] = origin[j, 0] - shift[0], origin[j, 1] - shift[1], origin[j, 2] - shift[2]
        if not np.isfinite(dist[i]):
            d[i, 0], d[i, 1], d[i, 2] = dirs[i, 0], dirs[i, 1], dirs[i, 2]
            t[i] = FAR
            continue
        if len(target):
            s0, s1, s2 = target[i, 0] - origin[j, 0], target[i, 1] - origin[j, 1], target[i, 2] - origin[j, 2]
        else:
            s0 = p[j, 0] + dirs[i, 0] * dist[i] - origin[j, 0]
            s1 = p[j, 1] + dirs[i, 1] * dist[i] - origin[j, 1]
            s2 = p[j, 2] + dirs[i, 2] * dist[i] - origin[j, 2]
        length = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if length > 0.0:
            d[i, 0], d[i, 1], d[i, 2] = s0 / length, s1 / length, s2 / length
        else:
            d[i, 0], d[i, 1], d[i, 2] = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        t[i] = length * (1.0 - 1e-5)


@kernel
def _offset(p, n, center, absolute, out):
    """``Tracer.offset_origin`` in float32 steps, as embree sees the points: each coordinate of p - center moved
    by ULP_OFFSET n float32 steps away from zero's side or by ``absolute`` n, whichever is larger."""
    p32, moved = np.empty(p.shape, np.float32), np.empty(p.shape, np.int32)
    for i in range(len(p)):
        for c in range(3):
            p32[i, c] = p[i, c] - center[c]
    bits = p32.view(np.int32)
    for i in range(len(p)):
        for c in range(3):
            of = np.int32(np.float32(ULP_OFFSET) * n[i, c])
            moved[i, c] = bits[i, c] - of if p32[i, c] < 0.0 else bits[i, c] + of
    stepped = moved.view(np.float32)
    for i in range(len(p)):
        for c in range(3):
            by_ulps, step = stepped[i, c] - p32[i, c], absolute * n[i, c]
            out[i, c] = p[i, c] + (by_ulps if abs(by_ulps) > abs(step) else step)
