"""Photon lights: virtual spherical lights with an emission of their own (Li et al., Virtual Blue Noise Lighting,
HPG 2022, sec. 3.3 and eq. 3).

Light j sits at y_j with normal n_j and radius r_j. A surface point y inside its sphere (||y - y_j|| <= r_j, facing
the same side) has a *share* s_j(y) of it: the weight 1 - (d / r_j)^2 normalised over the lights covering y, a
partition of unity. Photon splitting (sec. 3.3) gives each light the photons' reflected intensity times their
shares, I_j; its *catchment* A_j, the integral of s_j over the surface, comes from points dropped onto the surface
around the light (``methods.vbnl.catchment``). A diffuse light then emits ``L_j = I_j / A_j``, the
share-weighted mean radiance around it, and the radiance leaving y is ``sum_j s_j(y) L_j``.

Deviation, a local linear reconstruction (``fit_slopes``): each light also holds how its radiance changes across its
disc, a slope gamma_j about the centre c_j of its share, and y's radiance is
``sum_j s_j(y) L_j (1 + gamma_j . (y - c_j))``. A light whose disc is cut by a surface standing on it (a box on
the floor) averages the floor on one side only, so a mean alone carries the light of the open floor into the
corner: the first-order boundary bias of kernel estimates, which a local linear fit removes (Jones 1993, "Simple
boundary correction for kernel density estimation"; Fan and Gijbels 1996, ch. 3). The correction integrates to
zero over the light's share, so each light keeps its power (about the share's centre as the catchment measures it,
whose error is independent of the slopes: the correction adds nothing on average). On a floor lit as a ramp beside a
thin wall (``tests/engine/methods/test_vbnl.py``) the means alone put the wall's foot 6 % too bright, the slopes 2 %
too dark.

Deviation from eq. 3: the paper sums I_j / (pi r_j^2) over the covering lights with
the indicator of the sphere; the number of covering lights at a point varies by about +-50 % around its mean of
2 pi / sqrt(3) (alpha = 2), which is noise in every gather sample. Weighting by the shares instead gives a smooth
reconstruction with the same support, the same sampling (eq. 4-5) and the same total power, and the catchment
keeps edges and corners unbiased where lights have less surface around them (a density estimate from the
candidates' neighbours is 3-5 % off in the Cornell box, one way or the other depending on whether neighbours
across a corner counted). Lights hold
diffusely reflected light only and keep a single value each: the paper's directional emission profiles (16x16
octahedral maps) for lights on glossy surfaces are replaced by extending camera paths through metallic lobes
(``virtual_light_sampling``).

A light's support also stops where something stands on its plane (``reach``, per sector of its disc, found by
``methods.vbnl.open_reach``): a wall on the floor, a door leaf, a cabinet's side. Without it the floor of the next room
lies in a floor light's sphere, on its plane and facing its way: the light takes that room's photons and lends it its
light (5-10 % of the living room's photon light crosses such an occluder). Nor does it hold surface under a lid:
points with something straight over them (along their normal) nearer than ``LID`` r_j, such as the ceiling over a
glowing panel hung just below it, which the panel's back lights and the room does not see. Photon splitting and the
catchment pass each point's height under its lid (``lid_heights``; none for the gather's points).

The lights that may cover a point are listed in its cell of a hashed uniform grid (``LightGrid``): a light's
support is a thin disc (its sphere within ``SLAB`` r_j of its tangent plane), listed in every cell the disc's
bounding box touches. Compiled kernels (``core.compiled``) test a point against its cell's lights and share or
split in one loop (photon splitting of 10 M photons among 100 K lights: bench/vbnl_stages.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core.compiled import inline, kernel
from ...core.sampling import basis, orthonormal_basis
from ...sequence.persisted import record
from .morton import morton_codes, radix_tree

ALPHA = 2.0  # VSL radius r = alpha r_max (sec. 3.2)
SLAB = 0.005  # a light covers points within this many radii of its tangent plane: no share across thin walls
# (thicker slabs let rugs, sills and frames a few centimetres off a floor or wall share lights: with the same
# constant world in both renderers the living room is 1.27x Cycles' mean at 0.1, 1.23x at 0.05, 1.08x at 0.02;
# against a 16384-spp reference its Diffuse Indirect x colour is 1.089x at 0.02, 1.050x at 0.005, and its denoised
# picture at 64 pairs 0.0786 at 0.005 against 0.0907 at 0.02, for 32 % more time (more of it extends its paths);
# at 0.005 the Cornell boxes, the sphere of cornell_textured and the other converted scenes are the same or up to
# 3 % better)
CELL = 1.0  # the grid's cell, in median light radii (about 10 lights listed per cell at alpha = 2)
LISTED = 64  # at most this many cell entries per light on average: the cell grows for lights of very unequal size
SORTED_FROM = 32768  # lights from which photons are split a million at a time in the order of grid blocks
# (``Splitting``): at 100,000 lights (38 MB of discs, listings and sums, more than the cache) 700-760 ns a photon in
# path order, 350-520 ns in block order; at 4,096 and 20,000 lights, in cache anyway, path order is 10-15 % faster
SORTED_POINTS = 1 << 20  # points split at once in block order: more of them share a block's lights in cache
BLOCK = 2  # a block is 2^BLOCK cells a side
SECTORS = 16  # a light's reach (``PhotonLights.reach``) is kept per sector of its disc
LID = 0.25  # a point with something over it nearer than this many radii of a light is not the light's: light trapped
# there (a glowing panel 1 mm or 1 cm under a ceiling: 63 % and 59 % of the photons' light in two imported Cornell
# boxes, whose Diffuse Indirect is 2.2 and 1.13 times Cycles' without the test) does not reach the room it lights
SLOPE_CAP = 0.7  # at most this relative change of a light's radiance over its radius: 1 + gamma . (y - c) stays
# positive over the disc (|y - c| < 1.4 r where the share's centre is off the light's), so no clamp adds light
HASH = (73856093, 19349663, 83492791)  # Teschner et al. 2003, spatial hashing of a cell's integer coordinates


@record
@dataclass
class LightGrid:
    """The lights' supports hashed into a uniform grid of cubes of side ``cell`` from ``origin``: the lights that
    may cover a point in cell c are ``light[start[s]:start[s + 1]]`` with s the hash of c (``_slot``). Cells that
    share a slot share its list (the kernels test every light anyway), and no light is listed twice in a slot."""
    origin: np.ndarray  # (3,) the corner of cell (0, 0, 0)
    cell: float
    dims: np.ndarray  # (3,) int64: cells along each axis; points outside them are covered by no light
    start: np.ndarray  # (S+1,) int64, S a power of two
    light: np.ndarray  # (E,) int64
    discs: np.ndarray  # (N,8) each light's centre, normal, radius and whether its reach is cut: one cache line a light
    longest: int = 1  # the most lights listed in one slot
    reach: np.ndarray = field(default_factory=lambda: np.zeros((0, SECTORS)))  # (N, SECTORS) or none: whole discs

    @staticmethod
    def build(position: np.ndarray, normal: np.ndarray, radius: np.ndarray,
              reach: np.ndarray | None = None) -> "LightGrid":
        """The grid of lights at ``position`` (N,3) with unit ``normal``, ``radius`` (N,) and ``reach`` (N, SECTORS)
        if given (``PhotonLights.reach``)."""
        half = radius[:, None] * (np.sqrt(np.maximum(1.0 - normal * normal, 0.0)) + SLAB * np.abs(normal))
        half = half * (1.0 + 1e-6) + 1e-12 * np.abs(position)  # the disc's bounding box, with room for rounding
        lo, hi = position - half, position + half
        origin = lo.min(axis=0)
        extent = float(np.max(hi.max(axis=0) - origin))
        cell = max(CELL * float(np.median(radius)), 1e-9 * extent, 1e-300)
        while np.sum(np.prod(2.0 * half / cell + 2.0, axis=1)) > LISTED * len(radius):
            cell *= 2.0
        first = np.floor((lo - origin) / cell).astype(np.int64)
        span = np.floor((hi - origin) / cell).astype(np.int64) - first + 1
        count = np.prod(span, axis=1)
        light = np.repeat(np.arange(len(radius)), count)
        local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        rest, x = np.divmod(local, span[light, 0])
        z, y = np.divmod(rest, span[light, 1])
        slots = 1 << max(4, int(len(light) // 4).bit_length())
        slot = _slot(first[light, 0] + x, first[light, 1] + y, first[light, 2] + z, slots - 1)
        key = np.unique(slot * len(radius) + light)  # sorted by slot, each light once per slot
        slot, light = np.divmod(key, len(radius))
        start = np.searchsorted(slot, np.arange(slots + 1))
        discs = np.zeros((len(radius), 8))
        discs[:, :3], discs[:, 3:6], discs[:, 6] = position, normal, radius
        if reach is not None:  # only the lights whose reach is cut short somewhere test it
            discs[:, 7] = np.any(reach < radius[:, None], axis=1)
        return LightGrid(origin, cell, np.floor((hi.max(axis=0) - origin) / cell).astype(np.int64) + 1, start,
                         light, discs, max(int(np.max(np.diff(start))), 1),
                         np.zeros((0, SECTORS)) if reach is None else np.ascontiguousarray(reach, np.float64))


def _slot(x, y, z, mask):
    """The hash slot of integer cell coordinates (arrays, or scalars in a kernel)."""
    return ((x * HASH[0]) ^ (y * HASH[1]) ^ (z * HASH[2])) & mask


_slot_compiled = kernel(_slot)


@record
@dataclass
class PhotonLights:
    position: np.ndarray  # (N,3)
    normal: np.ndarray  # (N,3) unit, on the side the light shines to
    radius: np.ndarray  # (N,) r_j = alpha r_max,j
    intensity: np.ndarray  # (N,3) radiant intensity along the normal, from photon splitting
    catchment: np.ndarray | None = None  # (N,) A_j, the surface area of the light's share; None: pi r_j^2
    centre: np.ndarray | None = None  # (N,3) c_j, the centre of the light's share; None: its position
    slope: np.ndarray | None = None  # (N,3) gamma_j, the relative change of its radiance (``fit_slopes``); None: 0
    by_bounce: np.ndarray | None = None  # (N,B,3) intensity of the photons of at most 1, 2, ... B bounces
    # (N,3) the white-receiver intensity of the photons that came over one sharp glossy lobe
    # (``VirtualLights.caustic``); None: not kept apart
    caustic: np.ndarray | None = None
    # (N, SECTORS) how far the light reaches in each sector of its disc (``open_reach``); None: its whole disc
    reach: np.ndarray | None = None
    grid: LightGrid | None = field(default=None, repr=False)
    _tree: tuple | None = field(default=None, repr=False)  # ``tree``'s (box, order, nodes), made once

    def __post_init__(self):
        self.position = np.ascontiguousarray(self.position, np.float64)
        self.normal = np.ascontiguousarray(self.normal, np.float64)
        self.radius = np.ascontiguousarray(self.radius, np.float64)
        if self.grid is None and len(self.position):
            self.grid = LightGrid.build(self.position, self.normal, self.radius, self.reach)

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
        return self._over_area(self.intensity_upto(bounces))

    @property
    def caustic_radiance(self) -> np.ndarray | None:
        """(N,3) the radiance of ``caustic`` over each light's area (None where not kept apart)."""
        return None if self.caustic is None else self._over_area(self.caustic)

    def _over_area(self, intensity: np.ndarray) -> np.ndarray:
        """(N,3) intensities per light over its area A_j (0 where it has none)."""
        area = np.pi * self.radius * self.radius if self.catchment is None else self.catchment
        return np.where(area[:, None] > 0.0, intensity / np.maximum(area, 1e-300)[:, None], 0.0)

    def tree(self, box: tuple) -> tuple[np.ndarray, tuple]:
        """(order, nodes): the lights in the order of their Morton codes in ``box`` (the scene's), and the binary
        radix tree of the codes in that order (``morton.radix_tree``; a node's lights share its codes' leading bits,
        so it holds near lights): the gather's light tree (``virtual_light_sampling._descend``). Made once."""
        if self._tree is None or not all(np.array_equal(a, b) for a, b in zip(self._tree[0], box)):
            codes = morton_codes(self.position, box)
            order = np.argsort(codes, kind="stable")
            nodes = radix_tree(codes[order]) if len(order) > 1 else tuple(np.zeros(0, np.int64) for _ in range(5))
            self._tree = (tuple(np.array(b, np.float64) for b in box), order, nodes)
        return self._tree[1], self._tree[2]

    @property
    def linear(self) -> tuple[np.ndarray, np.ndarray]:
        """(slope, centre), each (N,3): the lights' local linear reconstruction as the gather's kernel reads it,
        radiance at y = L_j max(1 + slope_j . (y - centre_j), 0) (flat where no slopes were fitted)."""
        flat = self.slope is None
        return (np.zeros((len(self), 3)) if flat else self.slope,
                self.position if flat or self.centre is None else self.centre)

    @property
    def _kernel_grid(self) -> tuple:
        """What the kernels read of the lights: the grid with the lights' discs."""
        g = self.grid
        return g.origin, g.cell, g.dims, g.start, g.light, g.discs, g.longest, g.reach

    def shares(self, points: np.ndarray, normals: np.ndarray, lids: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pairs (point row, light, s_j(point)), by row: the lights whose sphere holds the point, facing its side and
        within ``SLAB`` r_j of their tangent plane (no light reaches through a wall or floor to the surface behind
        it, e.g. the sunlit sill outside a window), and, given the points' heights under a lid (``lid_heights``), no
        nearer to it than ``LID`` r_j; with shares 1 - (d / r_j)^2 that sum to one over each point's pairs."""
        if len(self) == 0 or len(points) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        return _share_pairs(_rows(points), _rows(normals), _lids(lids, len(points)), self._kernel_grid)

    def share_of(self, points: np.ndarray, normals: np.ndarray, light: np.ndarray,
                 lids: np.ndarray | None = None) -> np.ndarray:
        """(P,) s_j(point) of the given light j (P,) of each point: 0 outside its sphere."""
        rows, covering, share = self.shares(points, normals, lids)
        return np.bincount(rows, share * (covering == light[rows]), len(points))


def fit_slopes(position, normal, radius, reach, flat, light, halves) -> np.ndarray:
    """(N,3) gamma_j: each light's radiance as L_j (1 + gamma_j . (y - c_j)) over its share, L_j its mean there
    (``light``, the luminance of I_j / A_j) and c_j the share's centre (``vbnl.Catchment.centre``).

    The gradient is a weighted least-squares fit (a local linear estimate, Fan and Gijbels 1996, ch. 3) over the
    light's disc with the kernel k_j = 1 - (d / r_j)^2 (not normalised over the lights), as far as the disc
    reaches (``reach``): with S_j = integral k_j (y - b_j)(y - b_j)^T dA about the kernel's centre b_j, in closed
    form over the disc cut to its reach (``_kernel_moments``), and M_j = sum over photons of k_j(p) I_p (p - b_j)
    (their luminance), it solves S_j g = M_j in the light's tangent plane. Only lights whose surface is the whole
    disc up to its reach (``flat``: every catchment point within its reach landed on it) get a slope; on a curved
    part or over an edge the photons' support is not the disc's.

    Fitted over the share alone, a region a light spacing across, with moments from the catchment's points, the
    slopes of lights cut by a wall would be mostly the catchment's error in the share's centre (|gamma| r 0.4-0.7
    on an evenly lit floor), and that error, correlated with the slopes, would add 0.2-0.3 % to the Cornell boxes'
    Diffuse Indirect: the closed form has neither.

    ``halves`` (N, 2, 4): per light, the kernel-weighted luminance and its first moment (sum k_j I_p p) of the
    photons of even and of odd light paths, two independent estimates. Their difference measures the gradient's
    noise, and the gradient is shrunk by max(0, 1 - |g_odd - g_even|^2 / |g|^2) (an estimate of |g|^2 /
    (|g|^2 + its noise)), then capped at ``SLOPE_CAP`` per radius."""
    if len(radius) == 0:
        return np.zeros((0, 3))
    t, b = orthonormal_basis(normal)
    weight, middle, (s_tt, s_tb, s_bb) = _kernel_moments(radius, reach)
    det = s_tt * s_bb - s_tb * s_tb
    posed = flat & (light > 0.0) & (weight > 0.0) & (det > 1e-6 * (weight * radius * radius) ** 2)
    det = np.where(posed, det, 1.0)
    centre = position + middle[:, :1] * t + middle[:, 1:] * b

    def gradient(moment, total):  # S^-1 (sum k I (p - b)), in the plane's (t, b) coordinates
        m = moment - total[:, None] * centre
        m_t, m_b = (m * t).sum(axis=1), (m * b).sum(axis=1)
        return (s_bb * m_t - s_tb * m_b) / det, (s_tt * m_b - s_tb * m_t) / det
    g_t, g_b = gradient(halves[:, 0, 1:] + halves[:, 1, 1:], halves[:, 0, 0] + halves[:, 1, 0])
    d_t, d_b = gradient(halves[:, 0, 1:] - halves[:, 1, 1:], halves[:, 0, 0] - halves[:, 1, 0])
    signal = g_t * g_t + g_b * g_b
    kept = np.maximum(0.0, 1.0 - (d_t * d_t + d_b * d_b) / np.maximum(signal, 1e-300))
    slope = (kept / np.where(posed, light, 1.0))[:, None] * (g_t[:, None] * t + g_b[:, None] * b)
    size = np.sqrt((slope * slope).sum(axis=1)) * radius
    slope *= (np.minimum(size, SLOPE_CAP) / np.maximum(size, 1e-300))[:, None]
    return np.where((posed & np.isfinite(slope).all(axis=1))[:, None], slope, 0.0)


def sector_angle(position):
    """The angle, in ``orthonormal_basis``' plane coordinates, at ``position`` (in sectors, from 0 to ``SECTORS``)
    around a light's disc: sector k spans positions [k, k + 1)."""
    return position / SECTORS * 2.0 * np.pi - np.pi


def sector_of(x, y):
    """The sector (of ``SECTORS``, as a whole float) of the disc that holds the in-plane offset (x, y) from its
    centre: ``sector_angle``'s inverse, rounded down; numbers or arrays, in numpy and in kernels (``_sector``)."""
    return np.minimum(np.floor((np.arctan2(y, x) / (2.0 * np.pi) + 0.5) * SECTORS), SECTORS - 1)


_sector = inline(sector_of)


def _kernel_moments(radius, reach):
    """The kernel k = 1 - (rho / r)^2 over each light's disc cut to its reach in every sector (``sector_angle``):
    (integral k dA (N,), its centre (N,2), and the integrals of k (y - centre) (y - centre)^T dA as (xx, xy, yy),
    each (N,)). Per sector of angles [a, a + w] reaching R, integral k rho^n rho d rho = R^(n+2) / (n+2) -
    R^(n+4) / ((n+4) r^2) times the integral of the angles' cos / sin powers."""
    r = radius[:, None]
    far = r if reach is None else np.minimum(reach, r)
    w = 2.0 * np.pi / SECTORS
    a = sector_angle(np.arange(SECTORS))[None, :]

    def radial(n):
        return far ** (n + 2) / (n + 2) - far ** (n + 4) / ((n + 4) * r * r)
    weight = (w * radial(0)).sum(axis=1)
    first = np.stack([(radial(1) * (np.sin(a + w) - np.sin(a))).sum(axis=1),
                      (radial(1) * (np.cos(a) - np.cos(a + w))).sum(axis=1)], axis=1)
    middle = np.where(weight[:, None] > 0.0, first / np.maximum(weight, 1e-300)[:, None], 0.0)
    twice = (np.sin(2.0 * (a + w)) - np.sin(2.0 * a)) / 4.0
    xx = (radial(2) * (w / 2.0 + twice)).sum(axis=1) - weight * middle[:, 0] ** 2
    xy = (radial(2) * (np.sin(a + w) ** 2 - np.sin(a) ** 2) / 2.0).sum(axis=1) - weight * middle[:, 0] * middle[:, 1]
    yy = (radial(2) * (w / 2.0 - twice)).sum(axis=1) - weight * middle[:, 1] ** 2
    return weight, middle, (xx, xy, yy)


class Splitting:
    """Photon splitting (sec. 3.3) of batch after batch of points among ``lights``: their values (P, C) shared
    among the covering lights, kept apart by ``group``; ``raw`` values (P, R), if the splitting keeps any
    (``raw_groups``), weighted by each covering light's kernel 1 - (d / r_j)^2 instead of its share and kept
    apart by ``raw_group`` (``fit_slopes``' moments). With an executor ``pool``, each batch is cut in
    ``workers`` parts summed on its threads, each into a sum of its own held for the whole splitting (no array of
    the lights' size per batch). With more than ``SORTED_FROM`` lights, a part is put in the order of the grid
    blocks its points fall in first (``_in_block_order``), so that points that test the same lights come one
    after another and find them in cache; ``points`` says how many points are worth adding at once."""

    def __init__(self, lights: PhotonLights, groups: int, channels: int, pool=None, workers: int = 1,
                 raw_groups: int = 0, raw_channels: int = 0):
        self.lights, self.groups, self.pool = lights, groups, pool
        parts = max(1, workers) if pool is not None else 1
        self.sums = np.zeros((parts, len(lights) * groups, channels))
        self.raw_groups = raw_groups
        self.raw_sums = np.zeros((parts, len(lights) * raw_groups, raw_channels if raw_groups else 0))
        self.points = SORTED_POINTS if len(lights) > SORTED_FROM else 1

    def add(self, points: np.ndarray, normals: np.ndarray, values: np.ndarray, group: np.ndarray | None = None,
            lids: np.ndarray | None = None, raw: np.ndarray | None = None, raw_group: np.ndarray | None = None):
        """Shares the values of the points (P,3) with unit ``normals`` (and heights under a lid, ``lid_heights``)
        among the lights covering them, and weighs their ``raw`` values by those lights' kernels."""
        if len(self.lights) == 0 or len(points) == 0:
            return
        points, normals, values, lids = _rows(points), _rows(normals), _rows(values), _lids(lids, len(points))
        group = np.zeros(len(points), np.int64) if group is None else np.ascontiguousarray(group, np.int64)
        channels = values.shape[1]
        if self.raw_groups:  # one array for the kernels: the raw values after the shared ones, both groups in one
            values = np.ascontiguousarray(np.concatenate([values, raw], axis=1), np.float64)
            group = group + self.groups * (0 if raw_group is None else np.asarray(raw_group, np.int64))
        grid = self.lights._kernel_grid
        bounds = np.linspace(0, len(points), len(self.sums) + 1).astype(np.int64)

        def split(w):
            rows = slice(bounds[w], bounds[w + 1])
            part = (points[rows], normals[rows], lids[rows], values[rows], group[rows])
            if len(self.lights) > SORTED_FROM:
                part = _in_block_order(*part, grid)
            else:
                part = (*part, _slots(part[0], grid))
            _split(*part, self.groups, channels, grid, self.sums[w], self.raw_sums[w])

        if len(self.sums) == 1:
            split(0)
        else:
            list(self.pool.map(split, range(len(self.sums))))

    def total(self) -> np.ndarray:
        """(N, groups, C) the values shared so far."""
        return self.sums.sum(axis=0).reshape(len(self.lights), self.groups, self.sums.shape[2])

    def raw_total(self) -> np.ndarray:
        """(N, raw_groups, R) the raw values weighted so far."""
        return self.raw_sums.sum(axis=0).reshape(len(self.lights), self.raw_groups, self.raw_sums.shape[2])


def lid_heights(tracer, points: np.ndarray, normals: np.ndarray, reach: float) -> np.ndarray:
    """(P,) how far over each surface point, along its normal, the nearest surface lies (``reach`` and more: none
    that near), for the lights' ``LID`` test."""
    if len(points) == 0:
        return np.zeros(0)
    hits = tracer.intersect(tracer.offset_origin(points, normals), normals, tmax=np.full(len(points), reach))
    return np.where(hits.hit, hits.t, np.inf)


def _lids(lids, count: int) -> np.ndarray:
    """The points' heights under a lid as a contiguous float64 array; none given: no lid over any."""
    return np.full(count, np.inf) if lids is None else np.ascontiguousarray(lids, np.float64)


def _rows(a) -> np.ndarray:
    """``a`` as a C-ordered float64 array (the one layout the kernels are compiled for)."""
    return np.ascontiguousarray(a, np.float64)


@kernel
def _cell_of(p, grid):
    """(inside, x, y, z): whether the point ``p`` (3,) lies in the grid, and the integer coordinates of its cell."""
    origin, cell, dims = grid[0], grid[1], grid[2]
    fx, fy, fz = (p[0] - origin[0]) / cell, (p[1] - origin[1]) / cell, (p[2] - origin[2]) / cell
    inside = 0.0 <= fx < dims[0] and 0.0 <= fy < dims[1] and 0.0 <= fz < dims[2]
    return inside, np.int64(fx) if inside else 0, np.int64(fy) if inside else 0, np.int64(fz) if inside else 0


@kernel
def _slot_of(p, grid):
    """The hash slot of the grid cell that holds the point ``p`` (3,), or -1 outside the grid."""
    inside, x, y, z = _cell_of(p, grid)
    return _slot_compiled(x, y, z, len(grid[3]) - 2) if inside else -1


@kernel
def _slots(points, grid):
    """(P,) the hash slot of each point's cell (``_slot_of``)."""
    slot = np.empty(len(points), np.int64)
    for i in range(len(points)):
        slot[i] = _slot_of(points[i], grid)
    return slot


@kernel
def _in_block_order(points, normals, lids, values, group, grid):
    """Copies of the points (P,3), their normals, lids, values and groups in the order of the grid blocks (of 2^BLOCK
    x 2^BLOCK x 2^BLOCK cells, hashed) they fall in, without the points outside the grid (no light covers them),
    and their cells' slots (``_slots``): a counting sort."""
    slots = max((len(grid[3]) - 1) >> (3 * BLOCK), 1)
    cell_slots = len(grid[3]) - 2
    slot, cell_slot = np.empty(len(points), np.int64), np.empty(len(points), np.int64)
    first = np.zeros(slots + 1, np.int64)
    for i in range(len(points)):
        inside, x, y, z = _cell_of(points[i], grid)
        slot[i] = _slot_compiled(x >> BLOCK, y >> BLOCK, z >> BLOCK, slots - 1) if inside else -1
        cell_slot[i] = _slot_compiled(x, y, z, cell_slots)
        if slot[i] >= 0:
            first[slot[i] + 1] += 1
    for s in range(slots):
        first[s + 1] += first[s]
    inside = first[slots]
    p, n, v, g = np.empty((inside, 3)), np.empty((inside, 3)), np.empty((inside, values.shape[1])), \
        np.empty(inside, np.int64)
    h = np.empty(inside)
    c = np.empty(inside, np.int64)
    for i in range(len(points)):
        s = slot[i]
        if s >= 0:
            k = first[s]
            first[s] += 1
            p[k], n[k], h[k], v[k], g[k], c[k] = points[i], normals[i], lids[i], values[i], group[i], cell_slot[i]
    return p, n, h, v, g, c


@inline
def _within_reach(dx, dy, dz, disc, reach):
    """Whether the offset (dx, dy, dz) from a light's centre (its ``disc`` row) lies within its ``reach`` (SECTORS,)
    in the sector it falls in."""
    t0, t1, t2, b0, b1, b2 = basis(disc[3], disc[4], disc[5])
    x, y = dx * t0 + dy * t1 + dz * t2, dx * b0 + dy * b1 + dz * b2
    far = reach[int(_sector(x, y))]
    return x * x + y * y <= far * far


@kernel
def _covering(p, n, lid, s, grid, found, weight):
    """How many lights cover the point ``p`` (3,) of normal ``n`` and height ``lid`` under a lid in the cell of slot
    ``s`` (``_slot_of``); their indices and weights 1 - (d / r_j)^2 go to ``found`` and ``weight``."""
    start, listed, discs, reach = grid[3], grid[4], grid[5], grid[7]
    if s < 0:
        return 0
    k = 0
    for e in range(start[s], start[s + 1]):  # without a branch: whether a light covers the point is a coin toss
        j = listed[e]
        dx, dy, dz = p[0] - discs[j, 0], p[1] - discs[j, 1], p[2] - discs[j, 2]
        nx, ny, nz, r = discs[j, 3], discs[j, 4], discs[j, 5], discs[j, 6]
        r2 = r * r
        d2 = dx * dx + dy * dy + dz * dz
        found[k] = j
        weight[k] = max(1.0 - d2 / r2, 1e-12)  # the rim still counts
        inside = (d2 <= r2) & (n[0] * nx + n[1] * ny + n[2] * nz > 0.0) \
            & (abs(dx * nx + dy * ny + dz * nz) <= SLAB * r) & (lid >= LID * r)
        if inside and discs[j, 7] != 0.0:  # a branch, but only for the few lights that hold the point
            inside = _within_reach(dx, dy, dz, discs[j], reach[j])
        k += inside
    return k


@kernel
def _share_pairs(points, normals, lids, grid):
    """``PhotonLights.shares`` of the points (P,3) with ``normals``: (rows, lights, shares)."""
    longest = grid[6]
    found, weight = np.empty(longest, np.int64), np.empty(longest)
    rows, light, share = np.empty(4 * len(points), np.int64), np.empty(4 * len(points), np.int64), \
        np.empty(4 * len(points))
    m = 0
    for i in range(len(points)):
        k = _covering(points[i], normals[i], lids[i], _slot_of(points[i], grid), grid, found, weight)
        if m + k > len(rows):
            rows, light, share = _grown(rows, m + k), _grown(light, m + k), _grown(share, m + k)
        total = weight[:k].sum()
        for q in range(k):
            rows[m], light[m], share[m] = i, found[q], weight[q] / total
            m += 1
    return rows[:m].copy(), light[:m].copy(), share[:m].copy()


@kernel
def _grown(a, size):
    """A copy of ``a`` with room for at least ``size`` items."""
    b = np.empty(max(2 * len(a), size), a.dtype)
    b[:len(a)] = a
    return b


@kernel
def _split(points, normals, lids, values, group, slot, groups, channels, grid, out, raw_out):
    """Adds each point's first ``channels`` values times its shares to ``out[light * groups + group % groups]``
    and the rest times the lights' kernels to ``raw_out[light * raw groups + group // groups]``:
    ``Splitting.add``, the points' cells' ``slot`` given (``_slots``)."""
    longest = grid[6]
    found, weight = np.empty(longest, np.int64), np.empty(longest)
    raw_groups = raw_out.shape[0] // max(out.shape[0] // groups, 1)
    for i in range(len(points)):
        k = _covering(points[i], normals[i], lids[i], slot[i], grid, found, weight)
        total = weight[:k].sum()
        for q in range(k):
            share = weight[q] / total
            row = found[q] * groups + group[i] % groups
            for c in range(channels):
                out[row, c] += share * values[i, c]
            if raw_groups:
                row = found[q] * raw_groups + group[i] // groups
                for c in range(channels, values.shape[1]):
                    raw_out[row, c - channels] += weight[q] * values[i, c]
