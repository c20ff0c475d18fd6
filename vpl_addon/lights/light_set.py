"""Every light of a scene as one set: which light a light path starts from, and which one a light sample at a
shading point goes to."""
from __future__ import annotations

import numpy as np

from ..core.sampling import sample_cdf
from .emissive import EmissiveTriangles
from .environment import EnvironmentLight
from .light_tree import LightTree
from .world import WorldLight


class LightSet:
    """Every emitter of a scene. Light paths start from all of them, chosen in proportion to estimated power.
    Next-event estimation picks among the *local* ones (all but the world) by the light each can bring to the
    shading point (a light tree, ``light_tree``), while the world, which a cosine-weighted ray samples as well as
    anything can, gets its own sample at every light sample (the way Cycles' BSDF sample finds the sky), so a
    bright sun does not starve the sky of samples."""

    def __init__(self, scene=None, lights=None, center=np.zeros(3), radius=1.0):
        if scene is not None:
            lo, hi = scene.bounds
            radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
            center = 0.5 * (lo + hi)
            lights = list(scene.lights)
            emissive = EmissiveTriangles.from_scene(scene)
            if emissive is not None:
                lights.append(emissive)
            if scene.environment is not None:
                lights.append(EnvironmentLight(scene.environment.image, scene.environment.rotation))
            elif scene.world.max() > 0.0:  # a constant world needs no importance map
                lights.append(WorldLight(scene.world))
        self.center, self.radius = center, radius
        flux = np.array([max(light.flux_estimate(radius), 0.0) for light in lights], np.float64)
        self.lights = [light for light, f in zip(lights, flux) if f > 0.0]
        self.prob = _normalized(flux[flux > 0.0])
        self.world = next((light for light in self.lights if isinstance(light, (WorldLight, EnvironmentLight))), None)
        self.local = [light for light in self.lights if light is not self.world]
        self.tree = LightTree(self.local) if len(self.local) > 1 else None

    def __len__(self):
        return len(self.lights)

    def only(self, index: int) -> "LightSet":
        """The same set restricted to light ``index``."""
        return LightSet(lights=[self.lights[index]], center=self.center, radius=self.radius)

    def emit(self, count: int, rng: np.random.Generator, prob: np.ndarray | None = None, with_light: bool = False):
        """``count`` light-path starts, lights chosen with ``prob`` (default: by power); power is divided by the
        selection probability, so the mean over paths estimates the total emitted power. ``with_light`` adds the
        index of each start's light (path verification follows a light's paths when it moves)."""
        prob = self.prob if prob is None else prob
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        choice = sample_cdf(cdf, rng.random(count))
        origins, dirs, power = np.zeros((count, 3)), np.zeros((count, 3)), np.zeros((count, 3))
        for index, light in enumerate(self.lights):
            m = np.nonzero(choice == index)[0]
            if len(m) == count:  # every path from this light: no scattering into the rows
                origins, dirs, power = light.emit(count, rng, self.center, self.radius)
                origins, dirs = np.asarray(origins, np.float64), np.asarray(dirs, np.float64)
                power = power / prob[index]
            elif len(m):
                o, d, w = light.emit(len(m), rng, self.center, self.radius)
                origins[m], dirs[m], power[m] = o, d, w / prob[index]
        return (origins, dirs, power, choice) if with_light else (origins, dirs, power)

    def sample_incident(self, p, n, u_select, u1, u2, owner=None):
        """One sample of a local light per sample: (wi, dist, L_e / pdf including 1/p_select, normal at the light
        point or None, the index of each sample's light among the local ones, p_select). ``owner`` as in
        ``Light.sample_incident`` (the points p, n, the samples u); the light is chosen by the light tree
        (``selection``) from ``u_select``. The normal is zero where the light point is not on scene geometry
        (analytic lights), None if no light is on geometry."""
        owner = np.arange(len(p)) if owner is None else owner
        if len(self.local) == 1:
            out = self.local[0].sample_incident(p, n, u1, u2, owner)
            return out[0], out[1], out[2], out[3] if len(out) == 4 else None, np.zeros(len(owner), np.int64), \
                np.ones(len(owner))
        count = len(owner)
        wi, dist, weight, target_n = np.zeros((count, 3)), np.zeros(count), np.zeros((count, 3)), None
        choice, prob = self.tree.sample(p, n, owner, u_select)
        order = np.argsort(choice, kind="stable")  # the samples light by light, only the lights chosen
        counts = np.bincount(choice, minlength=len(self.local))
        ends = np.cumsum(counts)
        for index in np.nonzero(counts)[0]:
            m = order[ends[index] - counts[index]:ends[index]]
            points, at = _distinct(owner[m])  # per-point work only where the light is chosen
            out = self.local[index].sample_incident(p[points], n[points], u1[m], u2[m], at)
            wi[m], dist[m], weight[m] = out[0], out[1], out[2] / prob[m, None]
            if len(out) == 4:
                target_n = np.zeros((count, 3)) if target_n is None else target_n
                target_n[m] = out[3]
        return wi, dist, weight, target_n, choice, prob

    def local_pdf(self, p, n, w, which, chance=None):
        """(K,) the solid-angle pdf with which ``sample_incident`` draws direction w from point p (normal n), with
        the light ``which`` (index among the local lights) chosen: its selection probability (``chance`` if the
        caller has it from ``sample_incident``, else the light tree's, ``selection``) times its own pdf; NaN where
        that light cannot say (``Light.mis`` None)."""
        out = np.full(len(p), np.nan)
        for index, light in enumerate(self.local):
            m = np.nonzero(which == index)[0]
            found = light.mis(p[m], n[m], w[m]) if len(m) else None
            if found is not None:
                out[m] = (self.selection(p[m], n[m], which[m]) if chance is None else chance[m]) * found[2]
        return out

    def selection(self, p: np.ndarray, n: np.ndarray, which: np.ndarray) -> np.ndarray:
        """(K,) the probability that ``sample_incident`` chooses local light ``which`` (K,) at points p with
        normals n: by the light tree (``light_tree``), 1 where there is no choice to make."""
        if len(self.local) <= 1:
            return np.ones(len(p))
        return self.tree.probability(p, n, which)


def _distinct(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_inverse=True)``, in one pass where the values come sorted (a light's samples keep
    their points' order: the stable sort by light keeps the ascending owners of ``direct_light``'s batches)."""
    if len(values) and np.all(values[1:] >= values[:-1]):
        first = np.ones(len(values), bool)
        first[1:] = values[1:] != values[:-1]
        return values[first], np.cumsum(first) - 1
    return np.unique(values, return_inverse=True)


def _normalized(weights: np.ndarray) -> np.ndarray:
    return weights / weights.sum() if len(weights) and weights.sum() > 0 else weights
