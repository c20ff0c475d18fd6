"""Light paths kept from frame to frame and verified against the objects and lights that moved (Moreau, Doggett,
Sintorn, Path Verification for Dynamic Indirect Illumination, sec. 3.1-3.3, Algorithm 1).

``LightPathStore`` keeps every segment of the light paths a method traced (start point, direction, the power it
carries, path id, bounce, length to its hit or infinity when it left the scene) and the VPLs at their ends. In the
next frame each segment is tested against the bounding boxes (old and new position) of every object that moved
(``segments_crossing_boxes``, conservative like the paper's test); a path is cut at its first crossing segment, its
VPLs from there on are dropped, and it is traced again from that segment's start with its direction and power
(``light_paths.trace_paths(start=...)``), so only the broken tails cost rays (with T = 0; the threshold below
keeps more). Objects that did not move cost nothing: a frame in which nothing moved re-traces no segment.
``follow`` runs one frame of it for ``ir``'s paths, ``bidir``'s standard VPLs and ``vbnl``'s photons.

Moving lights (sec. 3.1): every path remembers its light. A light that moved rigidly carries its paths' emission
samples with it (point and direction, ``distribution_map.transform``), so their first segments move; a light whose
power or colour changed rescales its paths' power; a light whose shape changed (size, cone, radius) drops its paths.
The distribution maps of the lights that changed (``distribution_map``: DM_T the light's own emission distribution
over its cells, DM_C the kept paths per cell) then prune paths of over-full cells with probability
(DM_C - DM_T) / DM_C (eq. 1) and fill cells below target by sampling the light restricted to the cell.

Error threshold (sec. 3.3, eq. 2, Algorithm 1): a moved or box-crossing segment is first intersected again; if
the energy reflected at its new end (incident power x albedo) is within T of the original and the normal there is
the old one, the VPL moves to the new end with its energy, the next segment leaves the new end in its old direction
and is verified the same way, and the rest of the path is kept once a segment ends where it ended before. (The
paper aims the next segment at its old end. Measured on a moving lamp, that keeps the tails that had left the scene
and re-traces those that hit, second-bounce flux a third of a re-trace's; a test on the next direction's cosine
biases the same way. Replaying the direction where the normal is unchanged keeps the choice of which tails to keep
independent of where they went.) Otherwise the path is traced again from that segment, whose hit is not traced
twice. T = 0 turns the threshold off: every moved segment is traced again with a new continuation.

A light of a kind without a distribution map (sun, round area light, emissive triangles, world) that changed, a
light that appeared or vanished, or a change of the shading re-traces every path.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.color import largest
from ..core.compiled import kernel
from ..core.sampling import dot
from ..core.tracer import Hits
from ..gather.virtual_lights import VirtualLights
from ..materials.surface import arrival_factor, shade
from ..paths.light_paths import BATCH_PATHS, trace_paths, trace_until
from . import distribution_map as dm
from .motion import light_digest
from .persisted import record

THRESHOLD = 1e-3  # T of eq. 2, the paper's 0.1 %


def segments_crossing_boxes(origin: np.ndarray, direction: np.ndarray, length: np.ndarray,
                            boxes: list[tuple[np.ndarray, np.ndarray]], margin: float = 0.0) -> np.ndarray:
    """Segments origin + t direction, 0 <= t <= length (inf: a ray), that touch any of the axis-aligned boxes
    (slab test, boxes grown by ``margin``)."""
    if len(origin) == 0 or not boxes:
        return np.zeros(len(origin), bool)
    lo = np.array([np.asarray(b[0], np.float64) - margin for b in boxes]).reshape(-1, 3)
    hi = np.array([np.asarray(b[1], np.float64) + margin for b in boxes]).reshape(-1, 3)
    return _crossing(np.ascontiguousarray(origin, np.float64), np.ascontiguousarray(direction, np.float64),
                     np.ascontiguousarray(length, np.float64), lo, hi)


@kernel
def _crossing(origin, direction, length, lo, hi):
    """``segments_crossing_boxes`` over the boxes (lo, hi): per segment and box, the interval of t inside all
    three slabs; a direction parallel to a slab is inside it everywhere or nowhere."""
    out = np.zeros(len(origin), np.bool_)
    for i in range(len(origin)):
        for b in range(len(lo)):
            enter, leave = -np.inf, np.inf
            for a in range(3):
                o, d = origin[i, a], direction[i, a]
                if d == 0.0:
                    if o < lo[b, a] or o > hi[b, a]:
                        enter, leave = np.inf, -np.inf
                    continue
                inv = 1.0 / d
                t1, t2 = (lo[b, a] - o) * inv, (hi[b, a] - o) * inv
                enter, leave = max(enter, min(t1, t2)), min(leave, max(t1, t2))
            if enter <= leave and leave >= 0.0 and enter <= length[i]:
                out[i] = True
                break
    return out


class PathRows:
    """The rows of a table of path vertices or segments by their (path, bounce), sorted once and searched as often
    as asked: ``_verify`` looks up every bounce's segments in tables whose keys do not change while it runs (sorted
    again for every lookup, about 600,000 keys take a quarter of a baked frame's time)."""

    def __init__(self, path: np.ndarray, bounce: np.ndarray):
        keys = _key(path, bounce)
        self.order = np.argsort(keys, kind="stable")
        self.keys = keys[self.order]

    def find(self, path: np.ndarray, bounce: np.ndarray) -> np.ndarray:
        """Row of each (path, bounce), -1 where there is none."""
        if len(self.order) == 0:
            return np.full(len(path), -1, np.int64)
        wanted = _key(path, bounce)
        at = np.minimum(np.searchsorted(self.keys, wanted), len(self.order) - 1)
        return np.where(self.keys[at] == wanted, self.order[at], -1)


def _key(path: np.ndarray, bounce: np.ndarray) -> np.ndarray:
    return path.astype(np.int64) * 4096 + bounce


@record(fields=("paths", "next_id", "segments", "vpls", "light", "emitters", "light_prob", "rays_last_frame"))
class LightPathStore:
    """The segments and VPLs of light paths (VPL intensities divided by ``paths``, the number of paths the
    estimator averages over, which stays the same from frame to frame), and each path's light."""

    def __init__(self):
        self.paths = 0
        self.next_id = 0  # path ids in use are below this (filled paths get new ids)
        self.segments = {k: np.zeros((0, 3)) for k in ("origin", "direction", "power")}
        self.segments.update(path=np.zeros(0, np.int64), bounce=np.zeros(0, np.int32), length=np.zeros(0))
        self.vpls = VirtualLights.empty()
        self.light = np.zeros(0, np.int64)  # per path id: index of its light in ``emitters`` (-1: none)
        self.emitters = []  # the lights of the last frame
        self.light_prob = np.zeros(0)  # the probability each light's paths were divided by at emission
        self.rays_last_frame = 0  # rays traced for light paths in the last update (the paper's Fig. 7 count)

    def _recorder(self):
        recorded = []

        def record(bounce, origins, dirs, power, path, light=None):
            recorded.append((origins.copy(), dirs.copy(), power.copy(), path.copy(), np.full(len(path), bounce)))
            if light is not None:
                self._grow(int(path.max()) + 1 if len(path) else 0)
                self.light[path] = light
        return recorded, record

    def _grow(self, next_id: int) -> None:
        if next_id > len(self.light):
            self.light = np.concatenate([self.light, np.full(next_id - len(self.light), -1, np.int64)])
        self.next_id = max(self.next_id, next_id)

    def _segments(self, recorded, vpls):
        """The recorded segments, each with its length to the VPL of its (path, bounce), or inf if it left."""
        if not recorded:
            return None
        origin, direction, power, path, bounce = (np.concatenate(a) for a in zip(*recorded))
        length = np.full(len(path), np.inf)
        at = PathRows(vpls.path, vpls.bounce).find(path, bounce)
        found = at >= 0
        length[found] = np.linalg.norm(vpls.position[at[found]] - origin[found], axis=1)
        return dict(origin=origin, direction=direction, power=power, path=path.astype(np.int64),
                    bounce=bounce.astype(np.int32), length=length)

    def _append(self, vpls, segments):
        self.vpls = VirtualLights.concat([self.vpls, vpls])
        if segments is not None:
            self.segments = {k: np.concatenate([self.segments[k], segments[k]]) for k in self.segments}

    def _keep(self, segment_rows, vpl_rows) -> None:
        self.segments = {k: v[segment_rows] for k, v in self.segments.items()}
        self.vpls = self.vpls.take(np.nonzero(vpl_rows)[0])

    def trace(self, scene, tracer, lights, target: int, rng, max_bounces: int, light_prob=None,
              paths: int | None = None) -> None:
        """Trace new paths until about ``target`` VPLs (``light_paths.trace_until``), or exactly ``paths`` paths
        (photon splitting), replacing what was kept."""
        rays0 = tracer.rays_traced
        self.__init__()
        recorded, record = self._recorder()
        if paths is None:
            vpls, self.paths = trace_until(scene, tracer, lights, target, rng, max_bounces, light_prob, record)
        else:
            vpls = VirtualLights.concat([trace_paths(scene, tracer, lights, min(BATCH_PATHS, paths - first), rng,
                                                     max_bounces, light_prob, first, record=record)
                                         for first in range(0, paths, BATCH_PATHS)]).scaled(1.0 / max(paths, 1))
            self.paths = paths
        self._grow(self.paths)
        self.emitters = list(lights.lights)
        self.light_prob = np.asarray(lights.prob if light_prob is None else light_prob, np.float64)
        self._append(vpls, self._segments(recorded, vpls))
        self.rays_last_frame = tracer.rays_traced - rays0

    def update(self, scene, tracer, lights, boxes, rng, max_bounces: int, margin: float = 0.0,
               threshold: float = THRESHOLD) -> int | None:
        """Follow the lights that changed (sec. 3.1) and the objects that moved (sec. 3.2, ``boxes``: their old
        and new bounding boxes), verifying moved segments with the threshold of eq. 2; returns the number of
        paths traced again in part or whole (filled ones included), or None when the lights cannot be followed
        (a light appeared, vanished or changed without a distribution map): then every path must be traced."""
        rays0 = tracer.rays_traced
        self.rays_last_frame = 0
        new = list(lights.lights)
        if len(new) != len(self.emitters) or any(type(a) is not type(b) or a.name != b.name
                                                 for a, b in zip(self.emitters, new)):
            return None
        self.vpls = self.vpls.take(np.arange(len(self.vpls)))  # a copy: the last frame's lights stay as they were
        seg = self.segments = {k: v.copy() for k, v in self.segments.items()}
        moved = segments_crossing_boxes(seg["origin"], seg["direction"], seg["length"], boxes, margin)
        dropped = np.zeros(self.next_id, bool)
        refill = []
        for index, (old, light) in enumerate(zip(self.emitters, new)):
            if light_digest(old) == light_digest(light):
                continue
            if not (dm.supported(old) and dm.supported(light)):
                return None
            mine = self.light[seg["path"]] == index
            if dm.shape(old) != dm.shape(light) or ((old.power <= 0.0) & (light.power > 0.0)).any():
                dropped |= self.light == index  # emitted again below
                refill.append(index)
                continue
            scale = np.where(old.power > 0.0, light.power / np.where(old.power > 0.0, old.power, 1.0), 0.0)
            seg["power"][mine] *= scale
            self.vpls.intensity[self.light[self.vpls.path] == index] *= scale
            first = mine & (seg["bounce"] == 1)
            origin, direction = dm.transform(old, light, seg["origin"][first], seg["direction"][first])
            if not (np.array_equal(origin, seg["origin"][first]) and np.array_equal(direction,
                                                                                    seg["direction"][first])):
                seg["origin"][first], seg["direction"][first] = origin, direction
                moved |= first
                refill.append(index)
        self.emitters = new
        starts = self._distribute(refill, dropped, rng)
        if starts is None and not moved.any():
            return 0
        if dropped.any():  # (a copy of every segment otherwise)
            keep = ~dropped[self.segments["path"]]
            moved = moved[keep]
            self._keep(keep, ~dropped[self.vpls.path])
        restarted = self._verify(scene, tracer, lights, moved, max_bounces, threshold, rng)
        filled = 0
        if starts is not None:
            self._retrace(scene, tracer, lights, starts, rng, max_bounces)
            filled = len(starts[0])
        self.rays_last_frame = tracer.rays_traced - rays0
        return restarted + filled

    def _distribute(self, refill, dropped, rng):
        """Distribution maps of the lights ``refill`` (sec. 3.1): prune over-full cells (eq. 1, marks ``dropped``)
        and return the starts of the paths that fill the lacking cells (None if none)."""
        first = self.segments["bounce"] == 1
        parts = []
        for index in sorted(set(refill)):
            light = self.emitters[index]
            rows = np.nonzero(first & (self.light[self.segments["path"]] == index) &
                              ~dropped[self.segments["path"]])[0]
            count = int(np.prod(dm.bins(light)))
            cell = dm.cells(light, self.segments["origin"][rows], self.segments["direction"][rows])
            counts = np.bincount(cell, minlength=count).astype(np.float64)
            target = np.full(count, self.paths * self.light_prob[index] / count)
            kept = dm.prune(counts, target, cell, rng)
            dropped[self.segments["path"][rows[~kept]]] = True
            new_cells = dm.fill(counts, target, rng)  # from DM_C before pruning: E[paths in a cell] = DM_T
            if len(new_cells):
                origins, dirs, power = dm.sample(light, new_cells, rng)
                parts.append((origins, dirs, power / self.light_prob[index], np.full(len(new_cells), index)))
        if not parts:
            return None
        origins, dirs, power, light = (np.concatenate(a) for a in zip(*parts))
        ids = np.arange(self.next_id, self.next_id + len(light))
        self._grow(self.next_id + len(light))
        self.light[ids] = light
        return origins, dirs, power, ids, 1

    def _verify(self, scene, tracer, lights, moved, max_bounces, threshold, rng) -> int:
        """Algorithm 1 over the ``moved`` segments, all paths at once one bounce at a time: returns the number of
        paths traced again from a segment."""
        seg = self.segments
        first = np.full(max(self.next_id, 1), np.iinfo(np.int32).max, np.int64)
        np.minimum.at(first, seg["path"][moved], seg["bounce"][moved])
        pending = np.nonzero(moved & (seg["bounce"] == first[seg["path"]]))[0]
        restart, restart_hits = [], []  # the segments to trace again from, and their hits (already traced)
        extent = float(np.linalg.norm(np.subtract(*scene.bounds))) if threshold > 0.0 else 0.0
        if len(pending) and threshold > 0.0:  # the keys stay as they are until the paths are traced again below
            vpl_rows, segment_rows = PathRows(self.vpls.path, self.vpls.bounce), PathRows(seg["path"], seg["bounce"])
        while len(pending) and threshold > 0.0:
            origin, direction = seg["origin"][pending], seg["direction"][pending]
            hits = tracer.intersect(origin, direction, tinted=True)  # as ``trace_paths`` traces them
            at = vpl_rows.find(seg["path"][pending], seg["bounce"][pending])
            rows = np.nonzero(hits.hit & (at >= 0))[0]
            surf = shade(scene, direction, hits, rows)
            # the next segment leaves the new end in its old direction (Algorithm 1, lines 7-10, with the sampled
            # direction replayed rather than aimed at the old end), which is a sample of the new end's own lobe only
            # where the normal is the same: elsewhere the path is traced again. Whether a tail is kept must not
            # depend on where the tail went (which way it leaves, whether it hit), or the kept paths favour some
            # outcomes: the energy compared is the vertex's own, incident power x albedo
            after = segment_rows.find(seg["path"][pending[rows]], seg["bounce"][pending[rows]] + 1)
            old_dir = seg["direction"][np.maximum(after, 0)]
            new_energy = seg["power"][pending[rows]] * surf.albedo * arrival_factor(surf)[:, None]
            if hits.tint is not None:
                new_energy *= hits.tint[rows]
            old_energy = self.vpls.intensity[at[rows]] * (np.pi * self.paths)
            close = np.zeros(len(pending), bool)
            close[rows] = (np.abs(new_energy - old_energy) <= threshold * old_energy).all(axis=1) & \
                (largest(old_energy) > 0.0) & ~surf.glossy & \
                (dot(surf.smooth_normal, self.vpls.normal[at[rows]]) >= 1.0 - 1e-9) & \
                ((after < 0) | (dot(old_dir, surf.geometric_normal) > 0.0))
            left = ~hits.hit & np.isinf(seg["length"][pending])  # left the scene then and now
            restart.append(pending[~close & ~left])
            restart_hits.append(hits.take(~close & ~left))
            done, sel = pending[close], close[rows]
            position = surf.position[sel]
            same = np.linalg.norm(position - self.vpls.position[at[close]], axis=1) <= 1e-6 * extent
            self.vpls.position[at[close]] = position
            self.vpls.normal[at[close]] = surf.smooth_normal[sel]
            seg["length"][done] = hits.t[close]
            after = after[sel]
            go = (after >= 0) & (~same | moved[np.maximum(after, 0)])
            nxt = after[go]
            seg["origin"][nxt] = tracer.offset_origin(position[go], surf.geometric_normal[sel][go])
            pending = nxt
        if threshold <= 0.0:
            restart.append(pending)
        restart = np.concatenate(restart) if restart else np.zeros(0, np.int64)
        self._retrace(scene, tracer, lights, None, rng, max_bounces, restart,
                      Hits.concat(restart_hits) if restart_hits else None)
        return len(restart)

    def _retrace(self, scene, tracer, lights, starts, rng, max_bounces, restart=None, hits=None) -> None:
        """Trace paths again from the segments ``restart`` (their VPLs and segments from there on dropped; ``hits``:
        those segments' hits if traced already), or the new ``starts`` (origins, dirs, power, path ids, bounce) of
        filled paths."""
        if restart is not None:
            seg = self.segments
            cut = np.full(max(self.next_id, 1), np.iinfo(np.int32).max, np.int64)
            cut[seg["path"][restart]] = seg["bounce"][restart]
            again = {k: v[restart] for k, v in seg.items()}
            self._keep(seg["bounce"] < cut[seg["path"]], self.vpls.bounce < cut[self.vpls.path])
            groups = [((again["origin"][r], again["direction"][r], again["power"][r], again["path"][r], int(b)),
                       None if hits is None else hits.take(r))
                      for b in np.unique(again["bounce"]) for r in [np.nonzero(again["bounce"] == b)[0]]]
        else:
            groups = [(starts, None)]
        if not groups:
            return
        recorded, record = self._recorder()  # one record and one append: each copies every kept segment
        vpls = VirtualLights.concat([trace_paths(scene, tracer, lights, 0, rng, max_bounces, start=start,
                                                 record=record, start_hits=start_hits)
                                     for start, start_hits in groups])  # each from one common bounce
        vpls = vpls.scaled(1.0 / max(self.paths, 1))
        self._append(vpls, self._segments(recorded, vpls))

    def lights(self) -> VirtualLights:
        return self.vpls


def follow(store: LightPathStore, context, motion, target: int, reuse: bool = True, threshold: float = THRESHOLD,
           light_prob=None, paths: int | None = None) -> int:
    """One frame of a method's kept light paths (``ir``, ``bidir``'s standard VPLs, ``vbnl``'s photons: ``target``
    VPLs or exactly ``paths`` paths, as ``LightPathStore.trace``): nothing traced when nothing
    they depend on changed, ``update`` when objects or lights moved (and ``reuse``), every path traced again
    otherwise (the first frame, new shading, a light that cannot be followed) with ``light_prob`` choosing the
    lights (default: by power). Returns the number of paths traced in part or whole."""
    scene, tracer = context.scene, context.tracer
    kept = store.paths and not motion.first and not motion.shading_changed
    traced = None
    if kept and not (motion.moved_objects or motion.lights_changed):
        traced = store.rays_last_frame = 0
    elif kept and reuse:
        extent = float(np.linalg.norm(np.subtract(*scene.bounds)))
        traced = store.update(scene, tracer, context.lights, motion.boxes, context.rng, context.max_bounces,
                              margin=1e-5 * extent, threshold=threshold)
    if traced is None:
        store.trace(scene, tracer, context.lights, target, context.rng, context.max_bounces, light_prob, paths)
        traced = store.paths
    return traced


@record
@dataclass
class PlacedFromPaths:
    """What a method that places its lights again in every frame something moved keeps in a sequence (``bidir``'s
    standard VPLs, ``vbnl``'s photons): its light paths, followed by ``follow``, and the last frame's lights and
    info, reused as they are in a static frame."""
    paths: LightPathStore = field(default_factory=LightPathStore)
    lights: object = None
    info: dict = field(default_factory=dict)

    def advance(self, place, context, settings, motion):
        """The frame's (lights, info): the last ones if nothing moved, else ``place(context, settings, self,
        motion)``."""
        if self.lights is not None and motion.static(view_dependent=True):
            kept = {k: v for k, v in self.info.items() if k != "light_path_rays"}  # as any method's static frame
            return self.lights, {**kept, "light_paths": 0, "reused": True}
        self.lights, self.info = place(context, settings, self, motion)
        return self.lights, self.info
