"""Every light of a scene as one set: which light a light path starts from, and which one a light sample at a
shading point goes to."""
from __future__ import annotations

import numpy as np

from ..core.sampling import sample_cdf
from .emissive import EmissiveTriangles
from .environment import EnvironmentLight
from .world import WorldLight


class LightSet:
    """Every emitter of a scene. Light paths start from all of them, chosen in proportion to estimated power.
    Next-event estimation picks among the *local* ones (all but the world) by their importance at the shading
    point (``selection``), while the world, which a
    cosine-weighted ray samples as well as anything can, gets its own sample at every light sample (the way
    Cycles' BSDF sample finds the sky), so a bright sun does not starve the sky of samples."""

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
        flux = np.array([max(l.flux_estimate(radius), 0.0) for l in lights], np.float64)
        self.lights = [l for l, f in zip(lights, flux) if f > 0.0]
        self.prob = _normalized(flux[flux > 0.0])
        self.world = next((l for l in self.lights if isinstance(l, (WorldLight, EnvironmentLight))), None)
        self.local = [l for l in self.lights if l is not self.world]

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
            if len(m):
                o, d, w = light.emit(len(m), rng, self.center, self.radius)
                origins[m], dirs[m], power[m] = o, d, w / prob[index]
        return (origins, dirs, power, choice) if with_light else (origins, dirs, power)

    def sample_incident(self, p, n, u_select, u1, u2, owner=None):
        """One sample of a local light per sample: (wi, dist, L_e / pdf including 1/p_select, normal at the light
        point or None, the index of each sample's light among the local ones). ``owner`` as in
        ``Light.sample_incident`` (the points p, n, the samples u). The normal is zero where the light point is not
        on scene geometry (analytic lights), None if no light is on geometry."""
        owner = np.arange(len(p)) if owner is None else owner
        if len(self.local) == 1:
            out = self.local[0].sample_incident(p, n, u1, u2, owner)
            return out[0], out[1], out[2], out[3] if len(out) == 4 else None, np.zeros(len(owner), np.int64)
        count = len(owner)
        wi, dist, weight, target_n = np.zeros((count, 3)), np.zeros(count), np.zeros((count, 3)), None
        prob = self.selection(p)
        choice = np.minimum((np.cumsum(prob[owner], axis=1) < u_select[:, None]).sum(axis=1), len(self.local) - 1)
        for index, light in enumerate(self.local):
            m = np.nonzero(choice == index)[0]
            if len(m) == 0:
                continue
            points, at = np.unique(owner[m], return_inverse=True)  # per-point work only where the light is chosen
            out = light.sample_incident(p[points], n[points], u1[m], u2[m], at)
            wi[m], dist[m], weight[m] = out[0], out[1], out[2] / prob[owner[m], index][:, None]
            if len(out) == 4:
                target_n = np.zeros((count, 3)) if target_n is None else target_n
                target_n[m] = out[3]
        return wi, dist, weight, target_n, choice

    def local_pdf(self, p, n, w, which):
        """(K,) the solid-angle pdf with which ``sample_incident`` draws direction w from point p (normal n), with
        the light ``which`` (index among the local lights) chosen: its selection probability times its own pdf;
        NaN where that light cannot say (``Light.mis`` None)."""
        out = np.full(len(p), np.nan)
        prob = self.selection(p)
        for index, light in enumerate(self.local):
            m = np.nonzero(which == index)[0]
            found = light.mis(p[m], n[m], w[m]) if len(m) else None
            if found is not None:
                out[m] = prob[m, index] * found[2]
        return out

    def selection(self, p: np.ndarray) -> np.ndarray:
        """(N, L) probabilities of choosing each local light at points p: in proportion to its importance there
        (a light tree's idea in its simplest form: near a small lamp, the lamp), with 10 % spread uniformly so no
        light that could matter is starved."""
        if len(self.local) <= 1:  # no choice to make
            return np.ones((len(p), len(self.local)))
        imp = np.stack([light.importance(p, self.radius) for light in self.local], axis=1)
        total = imp.sum(axis=1, keepdims=True)
        share = np.where(total > 0, imp / np.where(total > 0, total, 1.0), 1.0 / len(self.local))
        return 0.9 * share + 0.1 / len(self.local)


def _normalized(weights: np.ndarray) -> np.ndarray:
    return weights / weights.sum() if len(weights) and weights.sum() > 0 else weights
