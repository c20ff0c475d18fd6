"""The state a method carries from frame to frame of an animation (the sequence methods of Hedman et al. and
Moreau et al. keep theirs; every method at least keeps what a static frame can reuse).

``SequenceState`` is handed to ``render(..., sequence=state)`` for every frame of a bake, in order:

* ``begin(scene)`` digests the frame (``motion.Snapshot``), compares it with the previous one (``motion.Motion``)
  and returns the tracer: the previous frame's BVH when no triangle moved, a new one otherwise;
* ``still(scene)`` is the frame without the objects that move anywhere in the sequence (``animated``, found by
  whoever runs the sequence: a bake looks over its frames before the first; an animation render, which cannot look
  ahead, ``learns`` them as they move, and so does a bake, for what its look-ahead missed) and a tracer of it, kept
  from frame to frame: what a method draws from the camera's view is found in it (vbnl's candidates), so that where
  the view did not change its lights stay where they were while an object moves;
* ``place(method, context, settings)`` places the frame's virtual lights with a ``methods.base.Method`` (render
  hands it in). A method that keeps its own state across frames (``smc``; ``ir``, ``bidir`` and ``vbnl`` their light
  paths, ``path_verification``) provides ``start(context, settings) -> state`` (a cold start, including any warm-up,
  so a chunk of frames can begin on another machine) and ``advance(state, context, settings, motion) -> (lights,
  info)``. For the others the rule is the static one: when nothing they depend on changed (geometry, lights,
  shading, and the camera for the view-dependent ones), the previous frame's lights are reused and no light path is
  traced; the placement generator is put back where it was after they were placed, so the frame renders exactly as
  that one.

The state saves as data (``dumps``: arrays and JSON, ``persisted``; its tracers are built again), so a bake saves
it after every frame and an interrupted bake resumes from the last finished frame with exactly the state an
uninterrupted bake would have had; a saved state is read only by the bake it belongs to (``key``). Frame ``f``
places its lights with ``frame_seed(seed, f)`` (``RenderSettings.placement_seed``) and samples its pixels with
``seed``, as does what a method draws from the camera's view (``MethodContext.camera_rng``: vbnl's candidates): its
random numbers do not depend on where the bake started, and the pixel noise and the lights' places do not flicker.
"""
from __future__ import annotations

import hashlib

import numpy as np

from ..core.tracer import Tracer
from ..materials.cutouts import cutouts
from .motion import Motion, Snapshot
from .persisted import pack, record, unpack


# The layout of the saved state and of every method's state in it: raised whenever one of them gains, loses or
# changes a field, so a state saved by an earlier engine is refused (the bake starts cold) rather than failing on a
# missing attribute in the middle of a frame. 2: smc keeps its rounds' hits for the "voronoi" areas. 3: vbnl's
# photon lights keep their light tree (``PhotonLights.tree``). 4: the state keeps the objects that move in the sequence
# (``SequenceState.animated``). 5: vbnl's photon lights keep their reach (``PhotonLights.reach``); the state keeps
# its tracers' centre (``SequenceState.center``). 6: the state is records of arrays and JSON (``persisted``); lights
# keep their camera visibility as a field.
STATE_FORMAT = 6


def frame_seed(seed: int, frame: int) -> int:
    """The seed of one frame: a hash of (seed, frame), so frames are independent and reproducible."""
    return int(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, (int(frame) + (1 << 31)) & 0xFFFFFFFF])
               .generate_state(1)[0] & 0x7FFFFFFF)


def _hex(*values) -> str:
    return hashlib.blake2b(repr(values).encode(), digest_size=16).hexdigest()


def _kept(held: tuple[str, Tracer] | None, digest: str, scene, threads: int | None,
          center: np.ndarray | None) -> tuple[str, Tracer]:
    """``held`` (digest, tracer) if it was built for ``digest``, else a tracer of ``scene``'s triangles taken from
    ``center`` (the old one closed); its ray count reset and the scene's cut-outs set (alpha may change from frame
    to frame without the triangles)."""
    if held is None or held[0] != digest:
        if held is not None:
            held[1].close()
        held = digest, Tracer(scene.triangles, threads=threads, center=center)
    held[1].rays_traced = 0
    held[1].cutouts = cutouts(scene)
    return held


@record(fields=("method", "frame", "snapshot", "motion", "lights", "info", "method_state", "bvh_builds", "rng_state",
                "animated", "learns", "center", "_threads"),
        transient={"_whole": lambda: None, "_still": lambda: None})
class SequenceState:
    """One method's state across the frames of a sequence."""

    def __init__(self, method: str):
        self.method = method
        self.frame: int | None = None  # the last frame begun
        self.snapshot: Snapshot | None = None
        self.motion: Motion | None = None
        self.lights = None  # the last frame's placed lights and info (static reuse)
        self.info: dict = {}
        self.method_state = None  # what a sequence method keeps (its ``start``/``advance``)
        self.bvh_builds = 0  # BVHs built over the whole sequence (static frames build none)
        self.rng_state = None  # the placement generator's state after the lights were last placed
        # the names of the objects that move anywhere in the sequence (None: not known, as in the viewport)
        self.animated: tuple[str, ...] | None = None
        self.learns = False  # ``animated`` gains each frame's moved objects (an animation render, a bake)
        # the point every frame's tracers take their float32 coordinates from: the first frame's centre, so what
        # stands still is traced to the same bits in every frame (a centre that moved with the bounds, an object
        # moving at the scene's edge or one learnt to move, moved lights all over the room); saved, so a resumed
        # bake traces as an unbroken one
        self.center: np.ndarray | None = None
        self._whole: tuple[str, Tracer] | None = None  # (digest of the triangles and threads, their tracer)
        self._still: tuple[str, Tracer] | None = None  # (digest of the still objects and threads, their tracer)
        self._threads: int | None = None  # the threads the tracer was asked for

    # -- per frame -------------------------------------------------------------------------------------------------
    def begin(self, scene, frame: int | None = None, threads: int | None = None) -> Tracer:
        """The frame's tracer (on ``threads`` CPU threads, None: every core): the previous frame's, unless the
        triangles or the threads changed."""
        snapshot = Snapshot.of(scene)
        self.motion = Motion.between(self.snapshot, snapshot)
        self.snapshot, self.frame = snapshot, frame
        if self.learns and not self.motion.first and self.motion.moved_objects:
            self.animated = tuple(sorted({*(self.animated or ()), *self.motion.moved_objects}))
        held, self._threads = self._whole, threads
        self._whole = _kept(held, _hex(snapshot.triangles, threads), scene, threads, self.center)
        if self.center is None:
            self.center = self._whole[1].center
        if self._whole is not held:
            self.bvh_builds += 1
        return self._whole[1]

    def still(self, scene):
        """(scene, tracer) of the frame ``begin`` digested without the ``animated`` objects; None when none of them
        is in it or nothing else is. The tracer is built again only when the rest changes (an object that moved
        although it was not named; the threads)."""
        rest = scene.without(self.animated or ())
        if rest is scene or len(rest.triangles) == 0:
            return None
        digest = _hex(sorted((name, d) for name, d in self.snapshot.objects.items() if name not in self.animated),
                      self._threads)
        self._still = _kept(self._still, digest, rest, self._threads, self.center)
        return rest, self._still[1]

    def place(self, method, context, settings):
        """The frame's lights from ``method``, a ``methods.base.Method`` (handed in, so the sequence machinery that
        methods build on imports none of them)."""
        motion = self.motion or Motion(first=True)
        if method.sequential:
            if self.method_state is None:
                self.method_state = method.start(context, settings)
            lights, info = method.advance(self.method_state, context, settings, motion)
        elif self.lights is not None and motion.static(view_dependent=not method.view_independent):
            lights = self.lights
            info = {**self.info, "light_paths": 0, "reused": True}
        else:
            lights, info = method.place(context, settings)
        stable = method.stable_lights
        if (info.get("reused") or stable) and self.rng_state is not None:
            # what the caller draws next (the gather's order of the lights) is drawn as in the frame the lights
            # were placed in (or, for stable slots, the first frame): a static frame renders exactly as that frame,
            # and a VPL that lives on stays in its interleaving subset
            context.rng.bit_generator.state = self.rng_state
        else:
            self.rng_state = context.rng.bit_generator.state
        self.lights, self.info = lights, {k: v for k, v in info.items() if k != "reused"}
        return lights, info

    def close(self) -> None:
        for held in (self._whole, self._still):
            if held is not None:
                held[1].close()
        self._whole = self._still = None

    # -- persistence -----------------------------------------------------------------------------------------------
    def dumps(self, key: str = "") -> bytes:
        """The state as the bytes of a file (``persisted.pack``), its tracers left out; ``key`` names what it
        belongs to (a bake's scene, settings and frame), which ``loads`` is given again."""
        return pack(self, {"format": STATE_FORMAT, "key": key})

    @staticmethod
    def loads(data: bytes, key: str = "") -> "SequenceState":
        """The state ``dumps`` wrote with the same ``key``; ValueError for anything else (the caller starts cold
        instead): a state of another format (a pickle of an earlier engine, which is never unpickled), of another
        scene, settings or frame, damaged bytes, or a file that holds no sequence state."""
        try:
            header, read = unpack(data)
        except ValueError as err:
            raise ValueError(f"unreadable sequence state ({err}): written by another version of VPL GI, or "
                             f"damaged") from None
        if header.get("format") != STATE_FORMAT:
            raise ValueError(f"a sequence state of format {header.get('format')}, where this engine reads "
                             f"{STATE_FORMAT}: written by another version of VPL GI, or damaged")
        if header.get("key") != key:
            raise ValueError("a sequence state of another scene, settings or frame")
        state = read()
        if not isinstance(state, SequenceState):
            raise ValueError("not a sequence state")
        return state
