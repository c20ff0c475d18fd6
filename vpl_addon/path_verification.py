"""Light paths kept from frame to frame and verified against the objects that moved (Moreau, Doggett, Sintorn,
Path Verification for Dynamic Indirect Illumination, sec. 3.2 "dynamic occlusions").

``LightPathStore`` keeps every segment of the light paths a method traced (start point, direction, the power it
carries, path id, bounce, length to its hit or infinity when it left the scene) and the VPLs at their ends. In the
next frame each segment is tested against the bounding boxes (old and new position) of every object that moved
(``segments_crossing_boxes``, conservative like the paper's test); a path is cut at its first crossing segment, its
VPLs from there on are dropped, and it is traced again from that segment's start with its direction and power
(``light_paths.trace_paths(start=...)``), so only the broken tails cost rays. Objects that did not move cost
nothing: a frame in which nothing moved re-traces no segment.

What is not here yet: moving lights (the paper's distribution maps DM_T / DM_C with pruning probability
(DM_C - DM_T) / DM_C, eq. 1, and filling) and the error threshold T of eq. 2 on the reflected energy; a change of a
light or of the shading re-traces every path.
"""
from __future__ import annotations

import numpy as np

from .light_paths import trace_paths, trace_until
from .virtual_lights import VirtualLights


def segments_crossing_boxes(origin: np.ndarray, direction: np.ndarray, length: np.ndarray,
                            boxes: list[tuple[np.ndarray, np.ndarray]], margin: float = 0.0) -> np.ndarray:
    """Segments origin + t direction, 0 <= t <= length (inf: a ray), that touch any of the axis-aligned boxes
    (slab test, boxes grown by ``margin``)."""
    crossing = np.zeros(len(origin), bool)
    if len(origin) == 0:
        return crossing
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / direction
        for lo, hi in boxes:
            lo, hi = np.asarray(lo, np.float64) - margin, np.asarray(hi, np.float64) + margin
            t1, t2 = (lo - origin) * inv, (hi - origin) * inv
            near = np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2))  # 0 * inf: inside the slab's plane
            far = np.where(np.isnan(t2), np.inf, np.maximum(t1, t2))
            parallel = direction == 0.0
            inside = (origin >= lo) & (origin <= hi)
            near = np.where(parallel, np.where(inside, -np.inf, np.inf), near)
            far = np.where(parallel, np.where(inside, np.inf, -np.inf), far)
            enter, leave = near.max(axis=1), far.min(axis=1)
            crossing |= (enter <= leave) & (leave >= 0.0) & (enter <= length)
    return crossing


class LightPathStore:
    """The segments and VPLs of ``paths`` light paths (VPL intensities divided by the path count)."""

    def __init__(self):
        self.paths = 0
        self.segments = {k: np.zeros((0, 3)) for k in ("origin", "direction", "power")}
        self.segments.update(path=np.zeros(0, np.int64), bounce=np.zeros(0, np.int32), length=np.zeros(0))
        self.vpls = VirtualLights.empty()
        self.rays_last_frame = 0  # rays traced for light paths in the last update (the paper's Fig. 7 count)

    @staticmethod
    def _recorder():
        recorded = []

        def record(bounce, origins, dirs, power, path):
            recorded.append((origins.copy(), dirs.copy(), power.copy(), path.copy(), np.full(len(path), bounce)))
        return recorded, record

    @staticmethod
    def _segments(recorded, vpls):
        """The recorded segments, each with its length to the VPL of its (path, bounce), or inf if it left."""
        if not recorded:
            return None
        origin, direction, power, path, bounce = (np.concatenate(a) for a in zip(*recorded))
        length = np.full(len(path), np.inf)
        if len(vpls):
            key = path.astype(np.int64) * 4096 + bounce
            vkey = vpls.path.astype(np.int64) * 4096 + vpls.bounce
            order = np.argsort(vkey)
            at = np.minimum(np.searchsorted(vkey[order], key), len(order) - 1)
            found = vkey[order][at] == key
            length[found] = np.linalg.norm(vpls.position[order[at[found]]] - origin[found], axis=1)
        return dict(origin=origin, direction=direction, power=power, path=path.astype(np.int64),
                    bounce=bounce.astype(np.int32), length=length)

    def _append(self, vpls, segments):
        self.vpls = VirtualLights.concat([self.vpls, vpls])
        if segments is not None:
            self.segments = {k: np.concatenate([self.segments[k], segments[k]]) for k in self.segments}

    def trace(self, scene, tracer, lights, target: int, rng, max_bounces: int, light_prob=None) -> None:
        """Trace new paths until about ``target`` VPLs (``light_paths.trace_until``), replacing what was kept."""
        rays0 = tracer.rays_traced
        self.__init__()
        recorded, record = self._recorder()
        vpls, self.paths = trace_until(scene, tracer, lights, target, rng, max_bounces, light_prob, record)
        self._append(vpls, self._segments(recorded, vpls))
        self.rays_last_frame = tracer.rays_traced - rays0

    def verify(self, scene, tracer, lights, boxes, rng, max_bounces: int, margin: float = 0.0) -> int:
        """Cut every path at its first segment that crosses a box and trace it again from there; returns the
        number of paths re-traced."""
        rays0 = tracer.rays_traced
        self.rays_last_frame = 0
        seg = self.segments
        crossing = segments_crossing_boxes(seg["origin"], seg["direction"], seg["length"], boxes, margin)
        if not crossing.any():
            return 0
        first = np.full(max(self.paths, 1), np.iinfo(np.int32).max, np.int64)
        np.minimum.at(first, seg["path"][crossing], seg["bounce"][crossing])
        restart = crossing & (seg["bounce"] == first[seg["path"]])
        again = {k: v[restart] for k, v in seg.items()}
        self.segments = {k: v[seg["bounce"] < first[seg["path"]]] for k, v in seg.items()}
        self.vpls = self.vpls.take(np.nonzero(self.vpls.bounce < first[self.vpls.path])[0])
        for bounce in np.unique(again["bounce"]):  # trace_paths continues from one common bounce
            rows = np.nonzero(again["bounce"] == bounce)[0]
            start = (again["origin"][rows], again["direction"][rows], again["power"][rows], again["path"][rows],
                     int(bounce))
            recorded, record = self._recorder()
            vpls = trace_paths(scene, tracer, lights, 0, rng, max_bounces, start=start, record=record)
            vpls = vpls.scaled(1.0 / max(self.paths, 1))
            self._append(vpls, self._segments(recorded, vpls))
        self.rays_last_frame = tracer.rays_traced - rays0
        return int(restart.sum())

    def lights(self) -> VirtualLights:
        return self.vpls
