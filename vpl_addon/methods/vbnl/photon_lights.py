"""Photon lights: virtual spherical lights with an emission of their own (Li et al., Virtual Blue Noise Lighting,
HPG 2022, sec. 3.3 and eq. 3).

Light j sits at y_j with normal n_j and radius r_j. A surface point y inside its sphere (||y - y_j|| <= r_j, facing
the same side) has a *share* s_j(y) of it: the weight 1 - (d / r_j)^2 normalised over the lights covering y, a
partition of unity. Photon splitting (sec. 3.3) gives each light the photons' reflected intensity times their
shares, I_j; its *catchment* A_j, the integral of s_j over the surface, comes from points dropped onto the surface
around the light (``methods.vbnl.catchment``). A diffuse light then emits ``L_j = I_j / A_j``, the
share-weighted mean radiance around it, and the radiance leaving y is ``sum_j s_j(y) L_j``.

Deviation from eq. 3, measured in bench/README.md: the paper sums I_j / (pi r_j^2) over the covering lights with
the indicator of the sphere; the number of covering lights at a point varies by about +-50 % around its mean of
2 pi / sqrt(3) (alpha = 2), which is noise in every gather sample. Weighting by the shares instead gives a smooth
reconstruction with the same support, the same sampling (eq. 4-5) and the same total power, and the catchment
keeps edges and corners unbiased where lights have less surface around them (a density estimate from the
candidates' neighbours was 3-5 % off in the Cornell box, one way or the other depending on whether neighbours
across a corner counted). Lights hold
diffusely reflected light only and keep a single value each: the paper's directional emission profiles (16x16
octahedral maps) for lights on glossy surfaces are replaced by extending camera paths through metallic lobes
(``virtual_light_sampling``).

The lights covering many points at once come from one scipy k-d tree query of the ``neighbours`` nearest light
centres, kept where the distance is below that light's radius.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

ALPHA = 2.0  # VSL radius r = alpha r_max (sec. 3.2)
SLAB = 0.02  # a light covers points within this many radii of its tangent plane: no share across thin walls
# (0.1 still let rugs, sills and frames a few centimetres off a floor or wall share lights: with the same constant
# world in both renderers the living room was 1.27x Cycles' mean at 0.1, 1.23x at 0.05, 1.08x at 0.02; the flat
# example scenes are unchanged and the sphere of cornell_textured within noise)


@dataclass
class PhotonLights:
    position: np.ndarray  # (N,3)
    normal: np.ndarray  # (N,3) unit, on the side the light shines to
    radius: np.ndarray  # (N,) r_j = alpha r_max,j
    intensity: np.ndarray  # (N,3) radiant intensity along the normal, from photon splitting
    catchment: np.ndarray | None = None  # (N,) A_j, the surface area of the light's share; None: pi r_j^2
    by_bounce: np.ndarray | None = None  # (N,B,3) intensity of the photons of at most 1, 2, ... B bounces
    neighbours: int = 8  # nearest centres examined by ``shares`` (about 3.6 cover a point at alpha = 2)
    tree: cKDTree | None = field(default=None, repr=False)

    def __post_init__(self):
        self.position = np.asarray(self.position, np.float64)
        if self.tree is None and len(self.position):
            self.tree = cKDTree(self.position)

    def __len__(self):
        return len(self.position)

    @property
    def density(self) -> np.ndarray:
        """rho_j = alpha^2 / (2 sqrt(3) r_j^2): lights per unit area around light j (eq. 8)."""
        return ALPHA * ALPHA / (2.0 * np.sqrt(3.0) * self.radius * self.radius)

    @property
    def radiance(self) -> np.ndarray:
        """(N,3) L_j = I_j / A_j: the radiance a diffuse light stands for (light of every bounce)."""
        return self.radiance_upto(None)

    def intensity_upto(self, bounces: int | None) -> np.ndarray:
        """(N,3) the intensity of the photons of at most ``bounces`` bounces (all if None or if the bounces were
        not kept apart)."""
        if bounces is None or self.by_bounce is None or self.by_bounce.shape[1] == 0:
            return self.intensity
        return self.by_bounce[:, min(max(bounces, 1), self.by_bounce.shape[1]) - 1]

    def radiance_upto(self, bounces: int | None) -> np.ndarray:
        """(N,3) L_j = I_j / A_j of the light of at most ``bounces`` bounces."""
        area = np.pi * self.radius * self.radius if self.catchment is None else self.catchment
        return np.where(area[:, None] > 0.0, self.intensity_upto(bounces) / np.maximum(area, 1e-300)[:, None], 0.0)

    def shares(self, points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pairs (point row, light, s_j(point)): the lights whose sphere holds the point, facing its side and within
        ``SLAB`` r_j of their tangent plane (no light reaches through a wall or floor to the surface behind it,
        e.g. the sunlit sill outside a window), with shares 1 - (d / r_j)^2 that sum to one over each point's
        pairs."""
        if len(self) == 0 or len(points) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        k = min(self.neighbours, len(self))
        dist, light = self.tree.query(points, k=k, distance_upper_bound=float(self.radius.max()), workers=-1)
        dist, light = dist.reshape(len(points), k), light.reshape(len(points), k)
        found = light < len(self)
        safe = np.where(found, light, 0)
        off_plane = np.abs(np.einsum("ikj,ikj->ik", points[:, None, :] - self.position[safe], self.normal[safe]))
        inside = found & (dist <= self.radius[safe]) & (np.einsum("ij,ikj->ik", normals, self.normal[safe]) > 0.0) \
            & (off_plane <= SLAB * self.radius[safe])
        rows, cols = np.nonzero(inside)
        light = light[rows, cols]
        w = np.maximum(1.0 - (dist[rows, cols] / self.radius[light]) ** 2, 1e-12)  # the rim still counts
        return rows, light, w / np.bincount(rows, w, len(points))[rows]

    def share_of(self, points: np.ndarray, normals: np.ndarray, light: np.ndarray) -> np.ndarray:
        """(P,) s_j(point) of the given light j (P,) of each point: 0 outside its sphere."""
        rows, covering, share = self.shares(points, normals)
        return np.bincount(rows, share * (covering == light[rows]), len(points))

    def spread(self, points: np.ndarray, normals: np.ndarray, values: np.ndarray, group: np.ndarray | None = None,
               groups: int = 1) -> np.ndarray:
        """(N, groups, C): per-point values (P, C) shared among the covering lights, kept apart by ``group`` (P,)
        in [0, groups); a point no light covers adds nothing. Photon splitting (sec. 3.3) with values = the
        photons' reflected intensities, grouped by bounce."""
        rows, light, share = self.shares(points, normals)
        values = np.asarray(values, np.float64)
        slot = light * groups + (0 if group is None else np.asarray(group)[rows])
        out = np.zeros((len(self) * groups, values.shape[1]))
        for c in range(values.shape[1]):
            out[:, c] = np.bincount(slot, share * values[rows, c], len(self) * groups)
        return out.reshape(len(self), groups, values.shape[1])
