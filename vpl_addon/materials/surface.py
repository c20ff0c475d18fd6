"""What a ray finds where it hits: position, normals turned toward the ray's origin side, material terms.

The one place that turns embree hits into shading data; the G-buffer, light paths and camera paths all use it.
Surfaces are two-sided (as in Cycles): both normals are flipped to face the incoming ray. Material inputs driven by
image textures (``textures``) are looked up here, the Normal input through a tangent-space normal map as Cycles'
Normal Map node applies it: N' = normalize(x T + y B + z N) with (x, y, z) = 2 colour - 1 and B = sign N x T, then
N + (N' - N) strength, normalised; a Bump node's height map bends it further (``_bumped``). Where that bends the
normal, the diffuse lobe's light from a direction w is scaled by Cycles' bump shadowing term (``bump_shadowing``),
which darkens the light that grazes the true surface.

The Principled BSDF's layers as Cycles stacks them (``svm/closure.h``): the metallic lobe weighs ``metallic``,
everything below it 1 - metallic; the dielectric specular layer (``microfacet``) sits on the diffuse lobe, which
keeps 1 - max(A) of its weight, A the layer's albedo toward the viewer (``microfacet.layer_albedo``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.sampling import cosine_hemisphere, dot, interpolated, normalize
from ..core.compiled import kernel
from ..core.rows import concat_fields, take, take_fields
from .microfacet import dielectric_fresnel, edge, scale_below_layer, smith_g1, specular_layer
from .textures import at_points, lookup

ROUGH_COAT = 0.5  # Roughness from which a dielectric layer counts as a rough coat (``Surface.rough_coat``)


@dataclass
class Surface:
    position: np.ndarray  # (K,3)
    geometric_normal: np.ndarray  # (K,3) facing the incoming ray
    shading_normal: np.ndarray  # (K,3) facing the incoming ray's side
    prim: np.ndarray  # (K,) triangle index
    material: np.ndarray  # (K,)
    albedo: np.ndarray  # (K,3) diffuse albedo: base colour x (1 - metallic) x what the specular layer leaves
    roughness: np.ndarray  # (K,)
    metallic: np.ndarray  # (K,) weight of the metallic GGX lobe (``microfacet``)
    emission: np.ndarray  # (K,3)
    specular: np.ndarray  # (K,3) F0 of the metallic lobe: the base colour (or texture)
    edge: np.ndarray  # (K,3) b of the F82-tint Fresnel (``microfacet.f82_b``)
    dielectric: np.ndarray  # (K,3) F0 x Specular Tint of the dielectric specular layer (0: none)
    eta: np.ndarray  # (K,) relative IOR of that layer (1: none)
    incident: np.ndarray  # (K,3) unit direction of the ray that found the point (the viewer is at -incident)
    smooth_normal: np.ndarray | None = None  # (K,3) the interpolated normal before any normal map (as shading_normal
    # when None), facing the incoming ray's side

    def __post_init__(self):
        if self.smooth_normal is None:
            self.smooth_normal = self.shading_normal

    @property
    def glossy(self) -> np.ndarray:
        """(K,) bool: whether the point has a glossy lobe, metallic or the dielectric layer."""
        return (self.metallic > 0.0) | (self.eta != 1.0)

    @property
    def rough_coat(self) -> np.ndarray:
        """(K,) bool: whether the point's glossy lobe is a rough dielectric layer alone (no metal, Roughness at least
        ``ROUGH_COAT``): a lobe nearly as broad as the diffuse one and a few per cent of the light, which fewer
        samples serve (``render.glossy_samples``, ``paths.vertices.at_metal``) and light samples alone light, without
        the lobe's own samples and MIS (``lights.direct``)."""
        return (self.metallic <= 0.0) & (self.eta != 1.0) & (self.roughness >= ROUGH_COAT)

    def __len__(self):
        return len(self.prim)

    def take(self, rows) -> "Surface":
        return take_fields(self, rows)

    @staticmethod
    def concat(parts: list["Surface"]) -> "Surface":
        return concat_fields(Surface, parts)


def shade(scene, dirs: np.ndarray, hits, rows: np.ndarray) -> Surface:
    """Surface data at ``hits`` for the rays ``rows`` (which must have hit), given their unit directions."""
    m, k = scene.materials, len(rows)
    layer = (m.specular_tint.astype(np.float64),
             *specular_layer(m.ior.astype(np.float64), m.specular.astype(np.float64)))  # per material: tint, F0, IOR
    prim, mat, bary, incident = np.empty(k, np.int32), np.empty(k, np.int32), np.empty((k, 3)), np.empty((k, 3))
    position, ng, ns = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    base, emission, tint = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    roughness, metallic, f0, eta, glass = np.empty(k), np.empty(k), np.empty(k), np.empty(k), np.empty(k, np.bool_)
    _hit_points(np.asarray(rows, np.int64), hits.prim, hits.u, hits.v, dirs, scene.triangles, scene.normals,
                scene.material, (m.base_color, m.roughness, m.metallic, m.emission, *layer, m.glass),
                (prim, mat, bary, incident, position, ng, ns), (base, roughness, metallic, emission, tint, f0, eta, glass))
    inputs = _inputs(scene, mat, prim, bary, ns, {"base_color": base, "roughness": roughness, "metallic": metallic,
                                                 "emission": emission, "normal": ns})
    if m.mix_other is not None:
        _blend(scene, mat, prim, bary, ns, inputs, layer, tint, f0, eta)
    smooth, normal = np.empty((k, 3)), np.empty((k, 3))
    _turned(incident, ng, ns, inputs["normal"], smooth, normal)  # toward the ray after the normal map, as Cycles
    if m.fresnel_mix is not None:  # Metallic as F(N . I) of a mix's Fresnel curve (``Materials.fresnel_mix``)
        curved = np.nonzero(m.fresnel_mix[mat] > 0.0)[0]
        if len(curved):
            inputs["metallic"][curved] = dielectric_fresnel(np.clip(-dot(smooth[curved], incident[curved]), 0.0, 1.0),
                                                            m.fresnel_mix[mat[curved]].astype(np.float64))
    base, metallic = inputs["base_color"], inputs["metallic"]
    metal = base  # the metallic lobe's F0: the Base Color, or a material's own (``Materials.metal_color``)
    if m.metal_color is not None and (m.metal_color[mat, 0] >= 0.0).any():
        metal = np.where(m.metal_color[mat] >= 0.0, m.metal_color[mat], base)
    edges, dielectric, below = (np.empty((k, 3)) for _ in range(3))
    _lobes(tint, f0, glass, base, metal, metallic, eta, edges, dielectric, below)
    scale_below_layer(below, inputs["roughness"], dielectric, eta, normal, incident)
    return Surface(position=position, geometric_normal=ng, shading_normal=normal, prim=prim, material=mat,
                   albedo=below, roughness=inputs["roughness"], metallic=metallic, emission=inputs["emission"],
                   specular=metal, edge=edges, dielectric=dielectric, eta=eta, incident=incident, smooth_normal=smooth)


@kernel
def _hit_points(rows, hit_prim, hit_u, hit_v, dirs, triangles, normals, material, tables, points, inputs):
    """Per hit ``rows`` of the rays (their triangles ``hit_prim``, barycentrics ``hit_u``, ``hit_v``, directions
    ``dirs``), in one pass: ``points`` (prim, material, barycentrics, incident direction and ``_geometry``'s
    position, geometric and interpolated normals) and ``inputs``, its material's row of each of ``tables`` (per
    material: Base Color, Roughness, Metallic, emission, Specular Tint, layer F0, IOR, glass), in float64."""
    prim, mat, bary, incident, position, ng, ns = points
    base_color, rough, metal, emit, tint_of, f0_of, eta_of, glass_of = tables
    base, roughness, metallic, emission, tint, f0, eta, glass = inputs
    for i in range(len(rows)):
        r = rows[i]
        t = hit_prim[r]
        b1, b2 = hit_u[r], hit_v[r]
        prim[i], bary[i, 0], bary[i, 1], bary[i, 2] = t, 1.0 - b1 - b2, b1, b2
        j = material[t]
        mat[i] = j
        roughness[i], metallic[i], f0[i], eta[i], glass[i] = rough[j], metal[j], f0_of[j], eta_of[j], glass_of[j]
        for c in range(3):
            incident[i, c] = dirs[r, c]
            base[i, c], emission[i, c], tint[i, c] = base_color[j, c], emit[j, c], tint_of[j, c]
    _geometry(triangles, normals, prim, bary, position, ng, ns)


@kernel
def _turned(incident, ng, ns, mapped, smooth, normal):
    """Turns the geometric normals ``ng`` (in place), the interpolated normals ``ns`` (into ``smooth``) and the
    normal-mapped ones ``mapped`` (into ``normal``) toward the side the rays ``incident`` come from."""
    for i in range(len(ng)):
        sign = -1.0 if ng[i, 0] * incident[i, 0] + ng[i, 1] * incident[i, 1] + ng[i, 2] * incident[i, 2] > 0.0 \
            else 1.0
        for c in range(3):
            ng[i, c] = sign * ng[i, c]
            smooth[i, c] = sign * ns[i, c]
            normal[i, c] = sign * mapped[i, c]


@kernel
def _lobes(tint, f0, glass, base, metal, metallic, eta, edges, dielectric, below):
    """The Principled BSDF's lobes per point from its material's Specular Tint, layer F0 and glass flag and its
    (textured) Base Color, metallic F0 (``metal``: the Base Color itself or its own) and Metallic: Base Color and
    metallic F0 clamped to [0, 1] (in place), F82's ``edges``, the layer's F0 x tint (``dielectric``) and the
    diffuse albedo before the layer takes its share (``below``). A ray stopped by a pane (``cutouts``) sees a white
    mirror: metallic F0, Metallic and tint 1, no layer (``eta`` 1)."""
    for i in range(len(glass)):
        f, pane = f0[i], glass[i]
        if pane:
            metallic[i], eta[i], f = 1.0, 1.0, 0.0
        for c in range(3):
            b, t = 1.0 if pane else min(max(base[i, c], 0.0), 1.0), 1.0 if pane else tint[i, c]
            base[i, c] = b
            s = 1.0 if pane else min(max(metal[i, c], 0.0), 1.0)
            metal[i, c] = s
            edges[i, c] = edge(s, t)
            dielectric[i, c] = f * t
            below[i, c] = (1.0 - metallic[i]) * b


def _blend(scene, mat, prim, bary, ns, inputs, layer, tint, f0, eta):
    """A Mix Shader's two sides at the points of materials that mix (``Materials.mix_other``), in place, by the
    mix's factor f (or its map) at each point: the colours, Metallic, emission and normal blended, (1 - f) the
    material's own row's + f the other's (the normal made unit again), which is exact for the diffuse lobe; the
    glossy lobe's shape (roughness, Specular Tint, layer F0 and IOR) drawn whole from one side, the other's with
    probability f by a number hashed from the point (``_hashed``), so that two lobes of different roughness
    are their sum in expectation, as Cycles sums them (one lobe of the blended roughness is up to 50 % brighter on
    a highlight's flank than their sum). ``layer``: every material's (Specular Tint, layer F0, IOR), whose rows the
    points ``tint``, ``f0`` and ``eta`` take."""
    m = scene.materials
    other = m.mix_other[mat]
    rows = np.nonzero(other >= 0)[0]
    if not len(rows):
        return
    f = m.mix_factor[mat[rows]].astype(np.float64)
    ids = m.mapped("mix")[mat[rows]]
    for t in np.unique(ids[ids >= 0]):
        sel = np.nonzero(ids == t)[0]
        f[sel] = np.clip(at_points(m.maps[t], scene, prim[rows[sel]], bary[rows[sel]], scalar=True), 0.0, 1.0)
    second = _inputs(scene, other[rows], prim[rows], bary[rows], ns[rows])
    if inputs["normal"] is ns:  # the caller's normals stay as they were
        inputs["normal"] = ns.copy()
    for name in ("base_color", "metallic", "emission", "normal"):
        mine, g = inputs[name], f.reshape(-1, *([1] * (inputs[name].ndim - 1)))
        mine[rows] = (1.0 - g) * mine[rows] + g * second[name]
    normal = inputs["normal"]
    normal[rows] = normalize(normal[rows])
    drawn = np.nonzero(_hashed(prim[rows], bary[rows]) < f)[0]  # the points whose lobe is the other side's
    at, theirs = rows[drawn], other[rows[drawn]]
    inputs["roughness"][at] = second["roughness"][drawn]
    tint[at], f0[at], eta[at] = (a[theirs] for a in layer)


def _hashed(prim: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(K,) numbers uniform in [0, 1) that depend on the hit alone (its triangle and barycentrics: SplitMix64's
    finaliser of their bits), so the same point always draws the same one, whichever ray finds it."""
    x = prim.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)
    x ^= np.ascontiguousarray(bary[:, 1]).view(np.uint64)
    x ^= np.ascontiguousarray(bary[:, 2]).view(np.uint64) << np.uint64(1)
    for shift, factor in ((30, 0xBF58476D1CE4E5B9), (27, 0x94D049BB133111EB)):
        x ^= x >> np.uint64(shift)
        x *= np.uint64(factor)
    x ^= x >> np.uint64(31)
    return (x >> np.uint64(11)).astype(np.float64) * 2.0 ** -53


def _inputs(scene, mat: np.ndarray, prim: np.ndarray, bary: np.ndarray, ns: np.ndarray,
            out: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
    """Per point, the material inputs an image can drive: their values, or the textures' where linked; ``normal``
    the shading normal after any normal map (not yet turned toward the ray). ``out``: the materials' own values
    at the points, when the caller has them (``_hit_points``), which the textures then replace in place."""
    m = scene.materials
    if out is None:
        out = {"base_color": m.base_color.astype(np.float64)[mat], "roughness": m.roughness.astype(np.float64)[mat],
               "metallic": m.metallic.astype(np.float64)[mat], "emission": m.emission.astype(np.float64)[mat],
               "normal": ns}
    if not any((m.mapped(name) >= 0).any() for name in (*out, "bump")):  # no material has a texture
        return out
    linked = {name: m.mapped(name)[mat] for name in out}
    bump = m.mapped("bump")[mat]
    if not any((ids >= 0).any() for ids in (bump, *linked.values())):
        return out
    out["normal"] = ns.copy()  # the caller's normals stay as they were; the other inputs are fresh copies
    for name, ids in linked.items():
        for t in np.unique(ids[ids >= 0]):
            sel = np.nonzero(ids == t)[0]
            tmap = m.maps[t]
            if name == "normal":
                out[name][sel] = _normal_mapped(scene, tmap, prim[sel], bary[sel], ns[sel])
            else:
                out[name][sel] = at_points(tmap, scene, prim[sel], bary[sel], scalar=name in ("roughness", "metallic"))
    for t in np.unique(bump[bump >= 0]):  # on the normal map's normal, as a Bump node fed by a Normal Map
        sel = np.nonzero(bump == t)[0]
        out["normal"][sel] = _bumped(scene, m.maps[t], prim[sel], bary[sel], out["normal"][sel])
    out["roughness"] = np.clip(out["roughness"], 0.0, 1.0)
    out["metallic"] = np.clip(out["metallic"], 0.0, 1.0)
    out["emission"] = np.maximum(out["emission"], 0.0)
    return out


def _normal_mapped(scene, tmap, prim, bary, ns) -> np.ndarray:
    """Cycles' Normal Map node in tangent space (``svm_node_normal_map``) at points with unflipped normals ``ns``."""
    t4 = interpolated(scene.tangents[prim], bary)
    t = t4[:, :3] - dot(t4[:, :3], ns)[:, None] * ns
    length = np.linalg.norm(t, axis=1, keepdims=True)
    t = np.where(length > 1e-12, t / np.maximum(length, 1e-300), 0.0)
    b = np.where(t4[:, 3:] < 0.0, -1.0, 1.0) * np.cross(ns, t)
    c = 2.0 * at_points(tmap, scene, prim, bary, scalar=False) - 1.0
    mapped = c[:, :1] * t + c[:, 1:2] * b + c[:, 2:] * ns
    if tmap.strength != 1.0:
        mapped = ns + (mapped - ns) * max(tmap.strength, 0.0)
    length = np.linalg.norm(mapped, axis=1, keepdims=True)
    return np.where(length > 1e-12, mapped / np.maximum(length, 1e-300), ns)


def _bumped(scene, tmap, prim, bary, ns) -> np.ndarray:
    """Cycles' Bump node (``svm_node_set_bump``) at points with unflipped normals ``ns``: normalize(N - grad h),
    then mixed with N by its Strength, h the height map (Distance folded into its factor). Cycles takes grad h
    from the height at the shading point and at points a fraction of a pixel away (surfgrad / det, which tends to
    the surface gradient); here it is the gradient itself: central differences of the bilinear height a quarter
    texel apart in UV, carried onto the triangle by the gradients of its UVs."""
    tri = scene.triangles[prim].astype(np.float64)
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    c = np.cross(e1, e2)
    area2 = dot(c, c)[:, None]
    ok = area2[:, 0] > 1e-30
    ga = np.where(ok[:, None], np.cross(e2, c) / np.maximum(area2, 1e-300), 0.0)  # gradients of the barycentrics
    gb = np.where(ok[:, None], np.cross(c, e1) / np.maximum(area2, 1e-300), 0.0)
    corners = scene.uvs[prim].astype(np.float64)
    d1, d2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    uv = interpolated(corners, bary)
    a, b, _, d, e, _ = tmap.uv
    image = scene.textures[tmap.image]
    step = 0.25 / (max(image.shape[:2]) * max(abs(a), abs(b), abs(d), abs(e), 1e-12))
    gradient = np.zeros_like(ns)
    for axis, along in ((0, d1[:, :1] * ga + d2[:, :1] * gb), (1, d1[:, 1:] * ga + d2[:, 1:] * gb)):
        offset = np.zeros(2)
        offset[axis] = step
        slope = (lookup(tmap, scene.textures, uv + offset, True) - lookup(tmap, scene.textures, uv - offset, True))
        gradient += (slope / (2.0 * step))[:, None] * along
    bumped = normalize(ns - np.nan_to_num(gradient, nan=0.0, posinf=0.0, neginf=0.0))
    strength = max(tmap.strength, 0.0)
    if strength != 1.0:
        bumped = normalize(strength * bumped + (1.0 - strength) * ns)
    return np.where(np.isfinite(bumped).all(axis=1, keepdims=True) & (dot(bumped, bumped) > 0.5)[:, None],
                    bumped, ns)


def bump_shadowing(smooth: np.ndarray, ns: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(M,) factor on the diffuse lobe's light from unit directions ``w`` at points whose normal map turned the smooth
    normal ``smooth`` into ``ns``: Cycles' ``bump_shadowing_term`` (Blender 5), after Conty Estevez et al. 2019,
    "A microfacet-based shadowing function to solve the bump terminator problem": 0 where w and ns lie on different
    sides of the smooth surface, else GGX's G1 at cos(smooth, w) for alpha^2 = min(1, tan^2(smooth, ns) / 8).
    1 where the normal map left the normal as it was."""
    cos_si, cos_sn, cos_ni = dot(smooth, w), dot(smooth, ns), dot(ns, w)
    cos_i, cos_d = np.abs(cos_si), np.minimum(np.abs(cos_sn), 1.0)
    a2 = np.clip(0.125 * (1.0 / np.maximum(cos_d * cos_d, 1e-300) - 1.0), 0.0, 1.0)
    g = np.where(cos_i >= 1.0, 1.0, np.where(cos_i < 1e-6, 0.0, smith_g1(a2, cos_i)))
    g = np.where(cos_si * cos_sn * cos_ni < 0.0, 0.0, g)
    return np.where(bent(smooth, ns), g, 1.0)


def bent(smooth: np.ndarray, ns: np.ndarray) -> np.ndarray:
    """(K,) bool: where a normal map turned the smooth normal ``smooth`` (K,3) into another shading normal ``ns``
    (per component: numpy's ``any(axis=1)`` over three columns is many times slower)."""
    return (smooth[:, 0] != ns[:, 0]) | (smooth[:, 1] != ns[:, 1]) | (smooth[:, 2] != ns[:, 2])


def bump_factor(ns: np.ndarray, smooth: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(M,) the bump shadowing term toward unit directions ``w`` at points with shading normals ``ns`` and smooth
    normals ``smooth`` (``Surface``): ``bump_shadowing`` where a normal map bent ns, 1 elsewhere."""
    out = np.ones(len(w))
    rows = np.nonzero(bent(smooth, ns))[0]
    if len(rows):
        out[rows] = bump_shadowing(smooth[rows], ns[rows], w[rows])
    return out


def arrival_factor(surface: Surface) -> np.ndarray:
    """(K,) what a photon arriving along ``surface.incident`` brings to the diffuse lobe, relative to the light
    per area it stands for: cos(ns, w) bump / |cos(smooth, w)| toward its origin w = -incident where a normal map
    bent ns (Cycles' view of that light: its cos with the mapped normal and ``bump_shadowing``; the photon's
    density holds the smooth normal's cos), 1 elsewhere. Bounded: at grazing w the bump term falls as
    |cos(smooth, w)| 4 sqrt(2) / (tan(tilt) sin), so the ratio stays below 4 sqrt(2) cos(tilt) <= 5.66."""
    out = np.ones(len(surface))
    ns, smooth = surface.shading_normal, surface.smooth_normal
    rows = np.nonzero(bent(smooth, ns))[0]
    if len(rows):
        w = -surface.incident[rows]
        cos_s = np.abs(dot(smooth[rows], w))
        out[rows] = np.where(cos_s > 0.0, diffuse_cosine(ns[rows], smooth[rows], w) / np.maximum(cos_s, 1e-300), 0.0)
    return out


def diffuse_cosine(ns: np.ndarray, smooth: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(M,) cos(theta) of the diffuse lobe toward unit directions ``w``: max(0, ns . w) times ``bump_factor``."""
    return np.maximum(dot(ns, w), 0.0) * bump_factor(ns, smooth, w)


def bounce(scene, tracer, surface: Surface, dirs: np.ndarray, rows: np.ndarray | None = None):
    """Rays from the points of ``surface`` (or from its points ``rows``, a ray each) along ``dirs``, offset off it;
    rays that would leave below the true surface are dropped. Returns (what the rays hit, the index of the ray
    each hit came from)."""
    return bounce_tinted(scene, tracer, surface, dirs, rows, tinted=False)[:2]


def bounce_tinted(scene, tracer, surface: Surface, dirs: np.ndarray, rows: np.ndarray | None = None,
                  tinted: bool = True):
    """``bounce`` for rays that carry the colour of the coloured glass they cross (``Tracer.intersect``'s
    ``tinted``): (what the rays hit, the index of the ray each hit came from, (H,3) the colour each hit's light
    keeps, or None where no glass on the way is coloured)."""
    position, normal = surface.position, surface.geometric_normal
    if rows is not None:  # the two fields a ray needs, not a whole record of the rows
        position, normal = take(position, rows), take(normal, rows)
    leave = np.nonzero(dot(dirs, normal) > 0.0)[0]
    hits = tracer.intersect(tracer.offset_origin(position[leave], normal[leave]), dirs[leave], tinted=tinted)
    rows = np.nonzero(hits.hit)[0]
    return shade(scene, dirs[leave], hits, rows), leave[rows], None if hits.tint is None else hits.tint[rows]


def diffuse_bounce(scene, tracer, surface: Surface, rng: np.random.Generator):
    """One cosine-weighted ray (the diffuse BSDF's sample) from every point of ``surface`` (``bounce``). Returns
    (what the rays hit, the index of the point each hit came from, the directions of all points, their cos
    theta)."""
    dirs, cos = cosine_hemisphere(rng.random(len(surface)), rng.random(len(surface)), surface.shading_normal)
    return (*bounce(scene, tracer, surface, dirs), dirs, cos)


@kernel
def _geometry(triangles, normals, prim, bary, position, ng, ns):
    """Where the hits (triangle ``prim``, barycentric ``bary``) are, in float64: the ``position``, the unit
    geometric normal ``ng`` of the triangle's winding (zero for a degenerate one) and the interpolated corner
    normals, unit, in ``ns`` (``ng`` where they cancel out)."""
    for i in range(len(prim)):
        t = prim[i]
        w0, w1, w2 = bary[i, 0], bary[i, 1], bary[i, 2]
        a0, a1, a2 = np.float64(triangles[t, 0, 0]), np.float64(triangles[t, 0, 1]), np.float64(triangles[t, 0, 2])
        b0, b1, b2 = np.float64(triangles[t, 1, 0]), np.float64(triangles[t, 1, 1]), np.float64(triangles[t, 1, 2])
        d0, d1, d2 = np.float64(triangles[t, 2, 0]), np.float64(triangles[t, 2, 1]), np.float64(triangles[t, 2, 2])
        position[i, 0], position[i, 1], position[i, 2] = w0 * a0 + w1 * b0 + w2 * d0, w0 * a1 + w1 * b1 + w2 * d1, \
            w0 * a2 + w1 * b2 + w2 * d2
        e10, e11, e12, e20, e21, e22 = b0 - a0, b1 - a1, b2 - a2, d0 - a0, d1 - a1, d2 - a2
        n0 = w0 * np.float64(normals[t, 0, 0]) + w1 * np.float64(normals[t, 1, 0]) + w2 * np.float64(normals[t, 2, 0])
        n1 = w0 * np.float64(normals[t, 0, 1]) + w1 * np.float64(normals[t, 1, 1]) + w2 * np.float64(normals[t, 2, 1])
        n2 = w0 * np.float64(normals[t, 0, 2]) + w1 * np.float64(normals[t, 1, 2]) + w2 * np.float64(normals[t, 2, 2])
        g0, g1, g2 = e11 * e22 - e12 * e21, e12 * e20 - e10 * e22, e10 * e21 - e11 * e20
        length = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        if length > 0.0:
            g0, g1, g2 = g0 / length, g1 / length, g2 / length
        ng[i, 0], ng[i, 1], ng[i, 2] = g0, g1, g2
        length = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        u0, u1, u2 = (n0 / length, n1 / length, n2 / length) if length > 0.0 else (n0, n1, n2)
        if u0 * u0 + u1 * u1 + u2 * u2 > 0.5:
            ns[i, 0], ns[i, 1], ns[i, 2] = u0, u1, u2
        else:
            ns[i, 0], ns[i, 1], ns[i, 2] = g0, g1, g2
