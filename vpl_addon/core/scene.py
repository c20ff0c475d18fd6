"""The engine's scene: world-space geometry, materials, lights, world and camera as numpy arrays.

Everything downstream of extraction reads only this. It is built either from Blender (``operators/scene/extract.py``)
or directly in code (tests, stress scenes). ``Scene.build`` sanitises the input on purpose: triangles with
non-finite corners or zero area are dropped (and counted per object so the caller can name them), shading normals
that are missing, non-finite or zero fall back to the geometric normal, non-finite UVs become 0, non-finite or
negative texels become 0 and a material input whose texture does not exist uses the input's value; tangents (for
normal maps) that are missing or unusable are made from the triangle's UVs; colour attributes that are
non-finite or negative become 0, and a missing one black (as Cycles reads it).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .camera import Camera


# inputs an image can drive (``mix``: a Mix Shader's factor, ``Materials.mix_other``)
INPUTS = ("base_color", "roughness", "metallic", "emission", "alpha", "normal", "bump", "mix")


@dataclass(frozen=True)
class TextureMap:
    """An image texture feeding one material input (Blender's Image Texture node and what lies between it and the
    input): which image and channel, through which UV transform, times which factor.

    The value at a UV is ``factor`` x the image's colour (``channel`` -1), one channel (0-2: R, G, B as a Separate
    Color node gives them, 3: the image's alpha) or, for a colour feeding a scalar input, its luminance. For the
    ``normal`` input the colour is a tangent-space normal (Normal Map node) and ``strength`` its Strength; for
    ``bump`` the value is a height (a Bump node's Height times its Distance, negative when inverted) and
    ``strength`` the node's Strength. A
    ``cutoff`` (alpha clip, as the glTF importer builds it for a MASK material: 1 - (value < cutoff)) makes the value
    1 where it reaches the cutoff and 0 below. With ``vertex`` the colour is multiplied by the mesh's colour
    attribute (Blender's Color Attribute node, ``Scene.colors``); ``image`` -1 then reads that colour alone."""

    image: int  # index into Scene.textures; -1: no image (with ``vertex``: the colour attribute alone)
    channel: int = -1  # -1 the colour, 0..2 one channel, 3 the alpha
    factor: tuple = (1.0, 1.0, 1.0)  # multiplies the value (glTF factors, a Multiply by a constant)
    uv: tuple = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)  # (a, b, c, d, e, f): u' = a u + b v + c, v' = d u + e v + f
    extension: str = "REPEAT"  # Image Texture extension: REPEAT, EXTEND or CLIP
    closest: bool = False  # interpolation Closest instead of Linear
    strength: float = 1.0  # Normal Map strength
    cutoff: float = -1.0  # alpha clip threshold on the value; negative: none
    vertex: bool = False  # times the interpolated colour attribute (``Scene.colors``)
    srgb: bool = False  # the image's RGB is sRGB-encoded: interpolated so, then made linear (Cycles' 8-bit images)


@dataclass
class Materials:
    """Material table indexed by the per-triangle material id (row 0 is the fallback grey diffuse).

    Values are the inputs' own; ``maps`` are the image textures that replace them where an input is linked
    (``map_of[input]`` indexes ``maps`` per material, -1 for none)."""

    names: list[str]
    base_color: np.ndarray  # (M,3) linear RGB albedo of the diffuse lobe; of glass, what crossing a face leaves
    roughness: np.ndarray  # (M,)
    metallic: np.ndarray  # (M,)
    emission: np.ndarray  # (M,3) emitted radiance, W/(m^2 sr): Emission Color x Strength
    specular_tint: np.ndarray  # (M,3) F82 tint of the metallic lobe and tint of the dielectric layer's F0
    ior: np.ndarray  # (M,) IOR of the dielectric specular layer
    specular: np.ndarray  # (M,) Specular IOR Level (0: no dielectric layer, 0.5: the IOR's own reflectance)
    alpha: np.ndarray  # (M,) coverage: 1 opaque, 0 a hole
    maps: list[TextureMap] = field(default_factory=list)
    map_of: dict[str, np.ndarray] = field(default_factory=dict)  # input -> (M,) int index into maps, -1 none
    transmission: np.ndarray | None = None  # (M,) Transmission Weight (Glass BSDF: 1); None: 0 everywhere
    pass_index: np.ndarray | None = None  # (M,) int Pass Index (the Material Index pass); None: 0 everywhere
    # (M,3) F0 of the metallic lobe where it is not the Base Color (a Mix Shader of a Diffuse and a Glossy BSDF:
    # the Glossy's Color), negative where it is; None: every material's is its Base Color
    metal_color: np.ndarray | None = None
    # (M,) the IOR of the Fresnel curve that weighs the metallic lobe against the rest at each point instead of
    # Metallic (such a Mix Shader by a Fresnel or a Layer Weight node: Cycles' F(N . I)), 0 where Metallic does;
    # None: 0 everywhere
    fresnel_mix: np.ndarray | None = None
    # (M,) the row a Mix Shader blends this material's inputs with, -1 for none, by ``mix_factor`` (M,) (its map
    # ``mix`` where linked): the second shader's weight; None: no material mixes
    mix_other: np.ndarray | None = None
    mix_factor: np.ndarray | None = None

    def __post_init__(self):
        if self.transmission is None:
            self.transmission = np.zeros(len(self.names), np.float32)
        if self.pass_index is None:
            self.pass_index = np.zeros(len(self.names), np.int32)

    @property
    def glass(self) -> np.ndarray:
        """(M,) bool: materials rendered as thin glass (``materials.cutouts``): Transmission Weight of at least 0.5
        on a dielectric (metallic below 0.5)."""
        return (self.transmission >= 0.5) & (self.metallic < 0.5)

    @staticmethod
    def make(rows: list[dict]) -> "Materials":
        """Rows of {name, base_color, roughness, metallic, emission, specular_tint, ior, specular, alpha,
        transmission, pass_index, metal_color, fresnel_mix, mix_other, mix_factor, maps}
        (``maps``: input name -> TextureMap; ``texture``: an image index for Base Color alone); missing keys take
        defaults: a grey diffuse without a specular layer."""
        rows = [{"name": "default_surface"}] + list(rows)  # Cycles' name of its fallback (in Cryptomatte)
        maps, map_of = _texture_maps(rows)
        m = Materials(
            names=[r["name"] for r in rows],
            base_color=_column(rows, "base_color", (0.8, 0.8, 0.8)).reshape(-1, 3),
            roughness=_column(rows, "roughness", 0.5),
            metallic=_column(rows, "metallic", 0.0),
            emission=_column(rows, "emission", (0.0, 0.0, 0.0)).reshape(-1, 3),
            specular_tint=_column(rows, "specular_tint", (1.0, 1.0, 1.0)).reshape(-1, 3),
            ior=_column(rows, "ior", 1.5),
            specular=_column(rows, "specular", 0.0),
            alpha=_column(rows, "alpha", 1.0),
            maps=maps, map_of=map_of,
            transmission=_column(rows, "transmission", 0.0),
            pass_index=_column(rows, "pass_index", 0, np.int32),
            **_mixing_columns(rows),
        )
        _clean(m)
        return m

    @property
    def listed_names(self) -> list[str]:
        """The names a Cryptomatte manifest lists: every material's but those of the rows that are only a Mix
        Shader's second side (``mix_other``), which keep their material's name in the passes."""
        if self.mix_other is None:
            return self.names
        second = set(self.mix_other[self.mix_other >= 0].tolist())
        return [name for i, name in enumerate(self.names) if i not in second]

    def mapped(self, name: str) -> np.ndarray:
        """(M,) index into ``maps`` of the texture driving input ``name`` per material, -1 for its value."""
        return self.map_of.get(name, np.full(len(self.names), -1, np.int32))

    @property
    def diffuse_albedo(self) -> np.ndarray:
        """Albedo of the diffuse lobe: what Cycles' ``Diffuse Color`` pass holds (metals have none)."""
        return self.base_color * (1.0 - self.metallic)[:, None]

    @property
    def glossy(self) -> bool:
        """Whether any material has a glossy (GGX) lobe, metallic or the dielectric specular layer: without one,
        nothing glossy is computed."""
        return bool((self.metallic > 0.0).any() | (self.mapped("metallic") >= 0).any()
                    | ((self.specular > 0.0) & (self.ior != 1.0)).any() | self.glass.any()
                    | (self.fresnel_mix is not None and (self.fresnel_mix > 0.0).any()))


@dataclass
class Environment:
    """The world as an equirectangular map (Blender's Environment Texture): radiance times the Background's strength
    and the rotation taking a world direction to the map's lookup direction (the Mapping node's)."""
    image: np.ndarray  # (H,W,3) float32 linear radiance, row 0 = bottom (v = 0)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))  # (3,3)

    @staticmethod
    def checked(image, rotation=None) -> "Environment | None":
        """The map made safe (NaN, infinite and negative texels 0; a rotation that is not one: none), or None for a
        map without texels or light."""
        image = np.asarray(image, np.float32)
        if image.ndim != 3 or image.shape[0] == 0 or image.shape[1] == 0 or image.shape[2] < 3:
            return None
        image = np.maximum(np.nan_to_num(image[..., :3], nan=0.0, posinf=0.0, neginf=0.0), 0.0)
        if not image.max() > 0.0:
            return None
        r = np.eye(3) if rotation is None else np.asarray(rotation, np.float64).reshape(3, 3)
        if not (np.isfinite(r).all() and np.allclose(r @ r.T, np.eye(3), atol=1e-6)):
            r = np.eye(3)
        return Environment(image, r)


@dataclass
class Scene:
    triangles: np.ndarray  # (T,3,3) float32 world-space corners
    normals: np.ndarray  # (T,3,3) float32 per-corner shading normals (unit)
    uvs: np.ndarray  # (T,3,2) float32
    material: np.ndarray  # (T,) int32 index into materials
    object_id: np.ndarray  # (T,) int32 index into object_names
    object_names: list[str]
    materials: Materials
    lights: list  # of ``lights.Light`` (named, not imported: the lights layer builds on core)
    camera: Camera
    world: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # background radiance RGB
    environment: Environment | None = None  # the world as a map (then ``world`` is not used)
    textures: list[np.ndarray] = field(default_factory=list)  # (h,w,3|4) float32, row 0 = bottom (v = 0); linear
    # values, but sRGB-encoded where the maps reading them say so (``TextureMap.srgb``)
    tangents: np.ndarray | None = None  # (T,3,4) float32 per-corner tangent and bitangent sign, for normal maps
    colors: np.ndarray | None = None  # (T,3,3) float32 per-corner linear RGB of the colour attribute each
    # triangle's material reads (Color Attribute node); None when no material reads one
    dropped: dict[str, int] = field(default_factory=dict)  # object name -> triangles dropped by build()
    max_bounces: int = 8  # diffuse bounce limit of light paths (Cycles' min(max_bounces, diffuse_bounces))
    # per object: its Pass Index (the Object Index pass) and its asset, an index into asset_names (the name of its
    # outermost parent, Cryptomatte's asset); None: 0 and the object itself
    object_pass_index: np.ndarray | None = None
    object_asset: np.ndarray | None = None
    asset_names: list[str] | None = None
    # (T,3,2) float32 per-corner UVs of the UV map lightmaps are baked in (``lightmap``); None: ``uvs``
    bake_uvs: np.ndarray | None = None

    def __post_init__(self):
        if self.object_pass_index is None:
            self.object_pass_index = np.zeros(len(self.object_names), np.int32)
        if self.object_asset is None:
            self.object_asset, self.asset_names = np.arange(len(self.object_names)), list(self.object_names)

    @staticmethod
    def build(triangles, materials: Materials, lights, camera, *, normals=None, uvs=None, material=None,
              object_id=None, object_names=None, world=(0.0, 0.0, 0.0), environment=None, textures=(),
              tangents=None, colors=None, max_bounces=8, object_pass_index=None, object_asset=None,
              asset_names=None, bake_uvs=None) -> "Scene":
        """Assemble a scene from raw arrays, dropping triangles that cannot be traced or shaded."""
        tri = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
        object_names = list(object_names or ["object"])
        material, object_id, normals, uvs, tangents, colors = _per_triangle(len(tri), material, object_id, normals,
                                                                            uvs, tangents, colors)
        keep, ng, area2 = _traceable(tri)
        dropped = _dropped(object_id[~keep], object_names)
        tri, ng, area2, uvs, material, object_id = (a[keep] for a in (tri, ng, area2, uvs, material, object_id))
        normals, tangents, colors = (None if a is None else a[keep] for a in (normals, tangents, colors))
        if bake_uvs is not None:  # the lightmap's UV map (``lightmap``), kept apart from the textures' UVs
            bake_uvs = np.nan_to_num(np.asarray(bake_uvs, np.float64).reshape(len(keep), 3, 2)[keep], nan=0.0,
                                     posinf=0.0, neginf=0.0)
        ng = ng / area2[:, None]
        sn = _shading_normals(normals, ng)
        uvs = np.nan_to_num(uvs, nan=0.0, posinf=0.0, neginf=0.0)
        material = np.where((material >= 0) & (material < len(materials.names)), material, 0).astype(np.int32)
        textures = [np.maximum(np.nan_to_num(np.asarray(t, np.float32), nan=0.0, posinf=0.0), 0.0)
                    for t in textures]
        materials = _usable_maps(materials, textures)
        colors = _colors(colors, materials, len(tri))
        tangents = _tangents(tri, ng, uvs, tangents) if (materials.mapped("normal") >= 0).any() else None
        return Scene(triangles=tri.astype(np.float32), normals=sn.astype(np.float32), uvs=uvs.astype(np.float32),
                     material=material, object_id=object_id.astype(np.int32), object_names=object_names,
                     materials=materials, lights=[l for l in lights if l.is_active], camera=camera,
                     world=np.maximum(np.nan_to_num(np.asarray(world, np.float32), nan=0.0, posinf=0.0), 0.0),
                     environment=None if environment is None else Environment.checked(environment.image,
                                                                                       environment.rotation),
                     textures=textures, dropped=dropped,
                     tangents=None if tangents is None else tangents.astype(np.float32),
                     colors=None if colors is None else colors.astype(np.float32),
                     max_bounces=max(0, int(max_bounces)),
                     object_pass_index=None if object_pass_index is None else np.asarray(object_pass_index, np.int32),
                     object_asset=None if object_asset is None else np.asarray(object_asset, np.int64),
                     asset_names=asset_names, bake_uvs=None if bake_uvs is None else bake_uvs.astype(np.float32))

    def without(self, objects) -> "Scene":
        """The scene without the triangles of the objects named in ``objects`` (the rest, their materials, lights,
        camera and world as they are); itself when none of them is in it."""
        names = set(objects)
        ids = [i for i, name in enumerate(self.object_names) if name in names]
        if not ids:
            return self
        keep = np.nonzero(~np.isin(self.object_id, ids))[0]
        per_triangle = ("triangles", "normals", "uvs", "material", "object_id", "tangents", "colors", "bake_uvs")
        return replace(self, **{name: None if getattr(self, name) is None else getattr(self, name)[keep]
                                for name in per_triangle})

    @property
    def geometric_normals(self) -> np.ndarray:
        """(T,3) unit face normals from the corner winding (counter-clockwise = front, as in Blender)."""
        tri = self.triangles.astype(np.float64)
        ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return ng / np.linalg.norm(ng, axis=1, keepdims=True)

    @property
    def triangle_areas(self) -> np.ndarray:
        tri = self.triangles.astype(np.float64)
        return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)

    @property
    def surface_area(self) -> float:
        return float(self.triangle_areas.sum())

    @cached_property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned box of the geometry (a unit box at the origin for an empty scene). Kept once made: every
        block's gather asks for it, and the living room's 141,365 triangles take 42 ms a time (a scene's triangles
        are never changed in place; a changed scene is a new ``Scene``, ``dataclasses.replace``)."""
        if len(self.triangles) == 0:
            return -np.ones(3), np.ones(3)
        pts = self.triangles.reshape(-1, 3).astype(np.float64)
        return pts.min(axis=0), pts.max(axis=0)


def _texture_maps(rows: list[dict]) -> tuple[list[TextureMap], dict[str, np.ndarray]]:
    """(the distinct texture maps of ``rows``, input name -> (M,) index into them per row, -1 for none): each row's
    ``maps`` and its ``texture`` (an image for Base Color alone, where ``maps`` gives none); ValueError for an input
    no texture drives."""
    maps: list[TextureMap] = []
    map_of = {name: np.full(len(rows), -1, np.int32) for name in INPUTS}
    for i, r in enumerate(rows):
        given = dict(r.get("maps", {}))
        if r.get("texture", -1) >= 0:
            given.setdefault("base_color", TextureMap(int(r["texture"])))
        for name, tmap in given.items():
            if name not in map_of:
                raise ValueError(f"material {r['name']!r}: no input {name!r} takes a texture ({INPUTS})")
            if tmap not in maps:
                maps.append(tmap)
            map_of[name][i] = maps.index(tmap)
    return maps, map_of


def _column(rows: list[dict], key: str, default, dtype=np.float32) -> np.ndarray:
    """The rows' values of ``key``, ``default`` where a row has none."""
    return np.array([r.get(key, default) for r in rows], dtype=dtype)


def _mixing_columns(rows: list[dict]) -> dict[str, np.ndarray]:
    """The ``Materials`` columns only some rows give, by name, each where at least one row gives it: metal_color
    (clipped to [0, 1], -1 for the rows whose metallic lobe is their Base Color), fresnel_mix (an IOR in [0, 1e3])
    and mix_other with mix_factor (a row out of the table mixes with none; the factor in [0, 1]), NaN read as 0."""
    columns = {}
    own = np.array(["metal_color" in r for r in rows])
    if own.any():
        metal = np.clip(np.nan_to_num(_column(rows, "metal_color", (0.0, 0.0, 0.0)).reshape(-1, 3)), 0.0, 1.0)
        columns["metal_color"] = np.where(own[:, None], metal, np.float32(-1.0))
    if any("fresnel_mix" in r for r in rows):
        columns["fresnel_mix"] = np.clip(np.nan_to_num(_column(rows, "fresnel_mix", 0.0), nan=0.0, posinf=0.0), 0.0,
                                         1e3)
    if any(r.get("mix_other", -1) >= 0 for r in rows):
        other = _column(rows, "mix_other", -1, np.int32)
        columns["mix_other"] = np.where((other > 0) & (other < len(rows)), other, -1).astype(np.int32)
        columns["mix_factor"] = np.clip(np.nan_to_num(_column(rows, "mix_factor", 0.0)), 0.0, 1.0)
    return columns


def _clean(m: Materials):
    """Makes the table's inputs usable, in place: NaN and infinities 0 (the IOR's 1.5); colours, roughness,
    metallic, alpha and transmission clipped to [0, 1], the IOR to [1e-3, 1e3]; specular and emission at least 0."""
    for a in (m.base_color, m.roughness, m.metallic, m.emission, m.specular_tint, m.specular, m.alpha,
              m.transmission):
        np.nan_to_num(a, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    np.nan_to_num(m.ior, copy=False, nan=1.5, posinf=1.5, neginf=1.5)
    np.clip(m.base_color, 0.0, 1.0, out=m.base_color)
    np.clip(m.roughness, 0.0, 1.0, out=m.roughness)
    np.clip(m.metallic, 0.0, 1.0, out=m.metallic)
    np.clip(m.specular_tint, 0.0, 1.0, out=m.specular_tint)
    np.clip(m.alpha, 0.0, 1.0, out=m.alpha)
    np.clip(m.transmission, 0.0, 1.0, out=m.transmission)
    np.clip(m.ior, 1e-3, 1e3, out=m.ior)
    np.maximum(m.specular, 0.0, out=m.specular)
    np.maximum(m.emission, 0.0, out=m.emission)


def _per_triangle(n: int, material, object_id, normals, uvs, tangents, colors) -> tuple:
    """The per-triangle inputs of ``Scene.build`` as arrays of ``n`` triangles: material and object ids (0 where not
    given), normals, tangents and colours (None where not given) and UVs (0 where not given)."""
    material = np.zeros(n, np.int32) if material is None else np.asarray(material, np.int32).reshape(n)
    object_id = np.zeros(n, np.int32) if object_id is None else np.asarray(object_id, np.int32).reshape(n)
    normals = None if normals is None else np.asarray(normals, np.float64).reshape(n, 3, 3)
    uvs = np.zeros((n, 3, 2)) if uvs is None else np.asarray(uvs, np.float64).reshape(n, 3, 2)
    tangents = None if tangents is None else np.asarray(tangents, np.float64).reshape(n, 3, 4)
    colors = None if colors is None else np.asarray(colors, np.float64).reshape(n, 3, 3)
    return material, object_id, normals, uvs, tangents, colors


def _traceable(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """((T,) bool the triangles that can be traced: finite corners and an area that is not zero against the size of
    their coordinates, (T,3) their normals from the winding, (T,) those normals' lengths: twice the areas)."""
    ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(ng, axis=1)
    scale = np.abs(tri).max(axis=(1, 2)) if len(tri) else np.zeros(0)
    with np.errstate(invalid="ignore"):
        keep = np.isfinite(tri).all(axis=(1, 2)) & np.isfinite(area2) & (area2 > (scale * 1e-6) ** 2)
    return keep, ng, area2


def _dropped(object_id: np.ndarray, object_names: list[str]) -> dict[str, int]:
    """Object name (its id where it has none) -> how many of the dropped triangles, of objects ``object_id``, are
    its."""
    dropped = {}
    for oid, count in zip(*np.unique(object_id, return_counts=True)):
        dropped[object_names[oid] if 0 <= oid < len(object_names) else str(oid)] = int(count)
    return dropped


def _shading_normals(normals: np.ndarray | None, ng: np.ndarray) -> np.ndarray:
    """(T,3,3) unit per-corner shading normals: the given ``normals`` made unit, the geometric normal ``ng`` where
    one is missing, not finite or zero (every corner's without ``normals``)."""
    if normals is None:
        return np.repeat(ng[:, None, :], 3, axis=1)
    length = np.linalg.norm(normals, axis=2, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        sn = normals / length
    bad = ~(np.isfinite(sn).all(axis=2) & (length[..., 0] > 1e-12))
    return np.where(bad[..., None], ng[:, None, :], sn)


def _colors(colors: np.ndarray | None, materials: Materials, count: int) -> np.ndarray | None:
    """(T,3,3) per-corner colour attributes of ``count`` triangles, non-finite and negative values 0 and black where
    none is given (as Cycles reads a missing one); None when no map of ``materials`` reads them."""
    if not any(t.vertex for t in materials.maps):
        return None
    if colors is None:
        return np.zeros((count, 3, 3))
    return np.maximum(np.nan_to_num(colors, nan=0.0, posinf=0.0, neginf=0.0), 0.0)


def _usable_maps(materials: Materials, textures: list[np.ndarray]) -> Materials:
    """The table with every texture map whose image is missing, empty or without the channel it reads unlinked
    (the input keeps its value); a copy when anything changes, so the caller's table stays as it was."""
    def usable(t: TextureMap) -> bool:
        if t.image == -1 and t.vertex:
            return t.channel < 3
        if not 0 <= t.image < len(textures):
            return False
        image = textures[t.image]
        return image.ndim == 3 and image.size > 0 and t.channel < image.shape[2]

    ok = np.array([usable(t) for t in materials.maps] + [True], bool)  # index -1 stays -1
    if ok.all():
        return materials
    return replace(materials, map_of={name: np.where(ok[ids], ids, -1).astype(np.int32)
                                      for name, ids in materials.map_of.items()})


def _tangents(tri: np.ndarray, ng: np.ndarray, uvs: np.ndarray, given: np.ndarray | None) -> np.ndarray:
    """(T,3,4) per-corner tangents (xyz, bitangent sign): the given ones where they are finite and non-zero, else
    the triangle's own UV tangent dP/du (and the sign of its UV winding); triangles whose UVs are degenerate get any
    tangent perpendicular to the face."""
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d1, d2 = uvs[:, 1] - uvs[:, 0], uvs[:, 2] - uvs[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    t = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * np.where(det < 0.0, -1.0, 1.0)[:, None]  # along dP/du
    length = np.linalg.norm(t, axis=1)
    fallback = np.where(np.abs(ng[:, :1]) < 0.9, np.cross(ng, [1.0, 0.0, 0.0]), np.cross(ng, [0.0, 1.0, 0.0]))
    ok = (np.abs(det) > 1e-20) & (length > 1e-20)
    t = np.where(ok[:, None], t / np.maximum(length, 1e-300)[:, None], fallback / np.linalg.norm(
        fallback, axis=1, keepdims=True))
    own = np.concatenate([t, np.where(det < 0.0, -1.0, 1.0)[:, None]], axis=1)
    own = np.repeat(own[:, None, :], 3, axis=1)
    if given is None:
        return own
    good = np.isfinite(given).all(axis=2) & (np.linalg.norm(given[..., :3], axis=2) > 1e-12)
    given = np.where(good[..., None], given, own)
    given[..., 3] = np.where(given[..., 3] < 0.0, -1.0, 1.0)
    return given
