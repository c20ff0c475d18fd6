"""The base of the light types: what every light tells the light set and the samplers (``Light``), and the
disc distant lights emit their paths from."""
from __future__ import annotations

import numpy as np

from ..core.sampling import concentric_disk, orthonormal_basis


def disc_facing(rng, dirs, center, radius):
    """Origins on discs of the given radius perpendicular to each travel direction, upstream of the scene."""
    x, y = concentric_disk(rng.random(len(dirs)), rng.random(len(dirs)))
    t, b = orthonormal_basis(dirs)
    return center + radius * (x[:, None] * t + y[:, None] * b) - 2.0 * radius * dirs


class Light:
    """Base of the light types: a name, total power for light selection and incident sampling."""

    name: str
    distant = False  # no position (the sun): the light tree keeps it beside its nodes
    planar = False  # emits from a plane through its bounds' centre, to the side its orientation's axis points to
    visible = False  # camera rays see it (Cycles' Ray Visibility > Camera): ``seen`` draws it (``paths.gbuffer``)

    @property
    def is_active(self) -> bool:
        """Emits and is well defined: a light with NaN or infinite numbers (a broken transform), or without a
        direction, is inert rather than a source of NaN."""
        flux = self.flux_estimate(1.0)
        numbers = [v for v in vars(self).values() if isinstance(v, (float, np.ndarray))]
        directions = [getattr(self, k) for k in ("direction", "normal")
                      if isinstance(getattr(self, k, None), np.ndarray)]
        return bool(np.isfinite(flux) and flux > 0.0 and all(np.isfinite(v).all() for v in numbers)
                    and all(np.linalg.norm(d) > 0.0 for d in directions))

    def flux_estimate(self, scene_radius: float) -> float:
        """Approximate emitted power (luminance-weighted), used only to choose between lights."""
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, float]:
        """Centre and radius of a sphere around the emitter (local lights only)."""
        raise NotImplementedError

    def orientation(self) -> tuple[np.ndarray, float, float]:
        """The directions the light emits in, as an orientation cone (Conty Estevez and Kulla 2018, sec. 4.1):
        (axis, theta_o, theta_e), every point of the light emitting within theta_e of a normal that lies within
        theta_o of the axis. Here every direction: theta_o = pi (local lights only, ``light_tree``)."""
        return np.array([0.0, 0.0, 1.0]), np.pi, 0.5 * np.pi

    def intensity_estimate(self) -> float:
        """Largest radiant intensity [W/sr] (luminance-weighted) toward any direction, the power a light tree's
        importance divides by d^2: P / (4 pi) here, an isotropic emitter's."""
        return self.flux_estimate(1.0) / (4.0 * np.pi)

    def sample_incident(self, p, n, u1, u2, owner=None):
        """Light samples toward shading points: ``owner`` (N,) gives the point of ``p`` (P,3) each sample (u1[i],
        u2[i]) belongs to (None: sample i is at point i). A light whose sampling has a per-point part (the
        spherical rectangle) computes it once per point."""
        if owner is not None:
            p, n = p[owner], n[owner]
        return self._sample_incident(p, n, u1, u2)

    def _sample_incident(self, p, n, u1, u2):
        raise NotImplementedError

    def directions(self, p, n, u1, u2, owner=None):
        """``sample_incident``'s (wi, dist, weight), where the weight may come as a function of the rows asked for,
        weigh(rows) -> (R,3): a light whose weight costs more than a shadow ray (the environment map's lookups)
        weighs only the samples the shadow rays found unblocked (``direct._accumulate``). Here all at once."""
        return self.sample_incident(p, n, u1, u2, owner)[:3]

    def mis(self, p: np.ndarray, n: np.ndarray, w: np.ndarray):
        """What a ray from points p (shading normals n) along unit directions w finds of the light, for multiple
        importance sampling of a glossy lobe against ``sample_incident``: (distance (P,), emitted radiance (P,3),
        the solid-angle pdf of ``sample_incident`` choosing w (P,)), radiance and pdf 0 where the ray misses it;
        a light that is scene geometry (an emissive mesh) adds the normal (P,3) of the surface each ray finds, so
        the shadow ray toward it stops off that surface (``Tracer.visible_through``'s target normal). None for a
        light that cannot say: its samples keep their full weight and lobe samples ignore it."""
        return None

    def seen(self, origins: np.ndarray, dirs: np.ndarray):
        """What camera rays from ``origins`` along unit ``dirs`` see of the light: (distance (N,), emitted radiance
        (N,3)), 0 where a ray misses it; an infinite distance for a light at infinity. None for a light with
        nothing to show (a point light of radius 0, an emissive mesh, which the rays see as geometry)."""
        return None

    def emit(self, count, rng, center, radius):
        raise NotImplementedError
