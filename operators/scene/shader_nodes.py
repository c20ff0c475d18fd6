"""Blender materials -> engine material rows: the Principled BSDF's inputs, and the image textures that drive them
read through the node patterns Blender users and its glTF importer build.

An input's link is followed back through reroutes to an Image Texture, across what the engine can carry along:
- Separate Color (RGB) / Separate RGB: one channel of the image (glTF's metallic-roughness texture: G roughness,
  B metallic);
- Mix Color (Multiply) or Math (Multiply) with a constant: a factor (glTF's base colour, roughness, metallic
  factors);
- Normal Map (tangent space) into Normal: the image is a tangent-space normal map of that strength and UV map;
- Bump into Normal: its Height image is a height map (times Distance), with its Strength, on top of a Normal Map
  feeding the Bump's Normal;
- a Color Attribute node (or an Attribute node's Color of a geometry attribute) in place of the image, or multiplied
  with it by a Mix Color (Multiply, factor 1): the mesh's colour attribute (vertex colours, glTF's COLOR_0).
The image's Vector comes from the default UV map, a UV Map node or Texture Coordinate's UV, through a Mapping node
(its location, rotation and scale as an affine UV transform). A Checker Texture of UV coordinates with constant
colours and scale stands where an image may: it becomes a 2x2 image read Closest. Links are followed through
reroutes and into and out of node groups. Anything else keeps the input's value, with one warning naming the
material, the input and the node.

Shaders: the Principled, Diffuse, Glossy (as the metallic lobe), Glass and Emission shaders; a Mix Shader
with a Transparent BSDF is an alpha cut-out of the other shader, one of a Diffuse and a Glossy BSDF by a constant
factor, an image or a Fresnel (or Layer Weight) curve their two lobes so weighted (``_diffuse_and_glossy``), one of
two other opaque shaders by a constant factor or an image their inputs blended at each point (``_blended``), an Add
Shader of an Emission shader makes the other glow; other mixes and sums render their heavier (first) shader, with a
warning. A Holdout shader renders black (its warning comes from ``unsupported``). Glass keeps as its Base Color the
colour light keeps crossing one of its faces (``materials.cutouts``): the Glass BSDF's Color, the square root of the
Principled BSDF's Base Color (Cycles tints each crossing of Principled glass so, and a closed solid by its Base
Color; measured in Blender 5.0: a slab of Base Color (0.25, 0.5, 1) passes (0.231, 0.461, 0.925) = (1 - F)^2 x
Base Color, a Glass BSDF slab of that Color its square, (0.058, 0.229, 0.920)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ...vpl_addon.core.color import srgb_to_linear
from ...vpl_addon.core.scene import Materials, TextureMap
from ...vpl_addon.materials.microfacet import constant_reflectance_tint

CHANNELS = {"Red": 0, "R": 0, "Green": 1, "G": 1, "Blue": 2, "B": 2}
# Principled BSDF inputs of layers the engine does not render: any value but 0 is named in a warning
UNRENDERED_LAYERS = ("Coat Weight", "Sheen Weight", "Subsurface Weight", "Anisotropic", "Thin Film Thickness",
                     "Diffuse Roughness")


def stored_as_srgb(image) -> bool:
    """Whether Cycles keeps ``image`` sRGB-encoded and interpolates it so (an 8-bit image in the sRGB colour space:
    it converts a lookup's result to linear, not the texels)."""
    return not image.is_float and image.colorspace_settings.name == "sRGB"


def image_pixels(image, alpha: bool = False, encoded: bool = False) -> np.ndarray | None:
    """(h,w,3) float32 linear RGB (RGBA with ``alpha``) of a Blender image, row 0 at the bottom, NaN and infinities
    0; None when it has no pixels (a missing file, a zero-size image). With ``encoded``, an image Cycles
    interpolates sRGB-encoded (``stored_as_srgb``) keeps its encoded values."""
    w, h = image.size
    if not image.has_data and w * h == 0:
        try:
            image.pixels[0]  # loads the file if it exists
        except (IndexError, RuntimeError):
            pass
        w, h = image.size
    if w * h == 0 or image.channels == 0:
        return None
    px = np.empty(w * h * image.channels, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, image.channels)
    rgb = px[..., :3] if image.channels >= 3 else np.repeat(px[..., :1], 3, axis=2)
    if stored_as_srgb(image) and not encoded:
        rgb = srgb_to_linear(rgb)
    if alpha:
        a = px[..., 3:4] if image.channels in (2, 4) else np.ones((h, w, 1), np.float32)
        if image.channels == 2:
            a = px[..., 1:2]
        rgb = np.concatenate([rgb, a], axis=2)
    return np.nan_to_num(rgb.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)


def output_shader(owner, socket: str = "Surface"):
    """The shader node feeding ``socket`` (Surface or Volume) of the active output of a material's, a world's or a
    light's node tree, or None without nodes or without a shader there."""
    tree = owner.node_tree
    if tree is None:
        return None
    outputs = [n for n in tree.nodes if n.type in ("OUTPUT_MATERIAL", "OUTPUT_WORLD", "OUTPUT_LIGHT")]
    active = [n for n in outputs if n.is_active_output] or outputs
    if not active:
        return None
    source = _source(active[0].inputs[socket])
    return None if source is None else source.node


# group tree pointer -> the Group node last entered through it: a Group Input inside leads back out through the
# node the chain came in by (chains are followed one at a time, so the last one entered is the one being followed)
_entered: dict[int, object] = {}


def _walk(socket):
    """(the output socket feeding ``socket`` or None, the last input socket on the way): links are followed through
    reroutes and into and out of node groups (a Group node's output continues at its tree's active Group Output, a
    Group Input at the Group node's input). Unlinked (or muted), the last input socket holds the value."""
    while socket.is_linked:
        link = socket.links[0]
        if getattr(link, "is_muted", False) or not link.is_valid:
            return None, socket
        node = link.from_node
        if node.type == "REROUTE":
            socket = node.inputs[0]
        elif node.type == "GROUP" and node.node_tree is not None:
            outputs = [n for n in node.node_tree.nodes if n.type == "GROUP_OUTPUT"]
            active = [n for n in outputs if n.is_active_output] or outputs
            inner = [i for i in active[0].inputs if i.identifier == link.from_socket.identifier] if active else []
            if not inner:
                return None, socket
            _entered[node.node_tree.as_pointer()] = node
            socket = inner[0]
        elif node.type == "GROUP_INPUT" and node.id_data.as_pointer() in _entered:
            group = _entered[node.id_data.as_pointer()]
            outer = [i for i in group.inputs if i.identifier == link.from_socket.identifier]
            if not outer:
                return None, socket
            socket = outer[0]
        else:
            return link.from_socket, socket
    return None, socket


def _source(socket):
    """The output socket feeding ``socket`` (``_walk``), None when none does."""
    return _walk(socket)[0]


def _value(socket):
    """The value an input stands for when nothing it reads is an output: its own, or that of the group input it is
    wired to (a tuple for colours and vectors)."""
    source, end = _walk(socket)
    value = (socket if source is not None else end).default_value
    return tuple(value) if hasattr(value, "__len__") else float(value)


def _same(a, b) -> bool:
    """Whether two socket wrappers are the same socket (bpy makes a new wrapper at every access)."""
    return a.as_pointer() == b.as_pointer()


def _plain(row: dict) -> bool:
    """Whether a material row can be one side of a blended Mix Shader (``MaterialTable._blended``): opaque, not
    glass, not glowing, and not itself a mix."""
    maps = row.get("maps", {})
    return row.get("transmission", 0.0) < 0.5 and row.get("alpha", 1.0) >= 1.0 and "alpha" not in maps and \
        not any(row.get("emission", ())) and "emission" not in maps and \
        not {"metal_color", "fresnel_mix", "mix_other"} & set(row)


def _fresnel_ior(socket) -> float | None:
    """The IOR of the Fresnel curve feeding ``socket``: a Fresnel node's Fac (its IOR), a Layer Weight's Fresnel
    (1 / (1 - Blend), Cycles' ``svm_node_layer_weight``), each with a constant input and its own normal; None for
    anything else."""
    source = _source(socket)
    if source is None or source.node.type not in ("FRESNEL", "LAYER_WEIGHT") or \
            _source(source.node.inputs["Normal"]) is not None:
        return None
    if source.node.type == "FRESNEL" and _constant(source.node.inputs["IOR"]) is not None:
        return max(float(_constant(source.node.inputs["IOR"])), 1.0)
    if source.node.type == "LAYER_WEIGHT" and source.name == "Fresnel" and \
            _constant(source.node.inputs["Blend"]) is not None:
        return 1.0 / max(1.0 - float(_constant(source.node.inputs["Blend"])), 1e-5)
    return None


def _constant(socket):
    """The value of an input nothing feeds (``_value``), None when an output does."""
    return None if _source(socket) is not None else _value(socket)


def _threshold(node) -> tuple[float, object] | None:
    """(cutoff, the socket compared) of an alpha clip: the glTF importer's 1 - (x < cutoff) (a Math Subtract from 1
    of a Math Less Than a constant) or a Math Greater Than a constant; None for any other node."""
    if node.type != "MATH" or node.use_clamp:
        return None
    if node.operation == "SUBTRACT" and _constant(node.inputs[0]) == 1.0 and _source(node.inputs[1]) is not None:
        inner = _source(node.inputs[1]).node
        if inner.type == "MATH" and inner.operation == "LESS_THAN" and not inner.use_clamp:
            node = inner
        else:
            return None
    elif node.operation != "GREATER_THAN":
        return None
    cutoff, compared = _constant(node.inputs[1]), _source(node.inputs[0])
    return None if cutoff is None or compared is None else (cutoff, compared)


def _attribute(out) -> str | None:
    """The colour attribute an output socket reads ('' for the mesh's default), None when it is not the Color of a
    Color Attribute node or of an Attribute node of the geometry."""
    node = out.node
    if node.type == "VERTEX_COLOR" and out.name == "Color":
        return node.layer_name
    if node.type == "ATTRIBUTE" and node.attribute_type == "GEOMETRY" and out.name == "Color":
        return node.attribute_name
    return None


def _mapping(node) -> tuple[np.ndarray, np.ndarray] | None:
    """(m (3,3), t (3,)) of a Mapping node with constant inputs, v' = m v + t; None if unsupported."""
    kind = node.vector_type
    loc, rot, scale = (_constant(node.inputs[k]) for k in ("Location", "Rotation", "Scale"))
    if kind not in ("POINT", "TEXTURE") or None in (loc, rot, scale):
        return None
    rx, ry, rz = rot
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    r = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]]) @ \
        np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])  # Blender's XYZ Euler: X first
    s = np.diag(scale)
    if kind == "POINT":
        return r @ s, np.array(loc, np.float64)
    if min(abs(v) for v in scale) < 1e-12:  # Texture: the inverse, the texture moves instead of the coordinates
        return None
    m = np.linalg.inv(s) @ r.T
    return m, -m @ np.array(loc, np.float64)


def _checker(node, m: np.ndarray, t: np.ndarray, fac: bool) -> tuple[np.ndarray, tuple] | None:
    """(a 2x2 texel image, the UV transform) that a Closest, Repeat lookup turns into Cycles' Checker Texture
    ``node`` (its Color output, or with ``fac`` its Fac: 1 and 0) at p = m (u, v, 0) + t; None when its Color1,
    Color2 or Scale is linked or p's z varies over the UVs. Cycles colours a point Color1 where the sum of the floors
    of (p Scale + 1e-6) 0.999999 is odd, Color2 where it is even: a texel is a cell of the pattern, the image one
    period."""
    c1, c2, scale = (_constant(node.inputs[k]) for k in ("Color1", "Color2", "Scale"))
    if None in (c1, c2, scale) or abs(m[2, 0]) + abs(m[2, 1]) > 1e-12:
        return None
    if fac:
        c1, c2 = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)

    def cell(x):  # a coordinate in cells of the pattern, nudged off integers as Cycles does
        return (x * scale + 1e-6) * 0.999999

    z_odd = int(math.floor(cell(t[2]))) % 2
    texels = np.empty((2, 2, 3), np.float32)
    for y in range(2):
        for x in range(2):
            texels[y, x] = (c1 if (x + y + z_odd) % 2 else c2)[:3]
    k = scale * 0.999999 / 2
    return texels, (k * m[0, 0], k * m[0, 1], cell(t[0]) / 2, k * m[1, 0], k * m[1, 1], cell(t[1]) / 2)


class _Unsupported(Exception):
    """A node on a texture chain that the engine does not read, and why (a phrase that follows "is not supported"):
    ``MaterialTable._map`` warns and the input keeps its value."""


@dataclass
class _Chain:
    """A texture chain followed back from the input it feeds (``_followed``): the output reached and what the nodes
    on the way make of its value."""
    out: object  # the output socket reached: an image's, a checker's or a colour attribute's; None past constants
    normal: bool  # a Normal Map node is still to come (the chain feeds a Normal input)
    channel: int = -1  # -1 the colour, 0..2 one channel (Separate Color), 3 the alpha
    factor: np.ndarray = field(default_factory=lambda: np.ones(3))  # the constants the Multiplies bring
    strength: float = 1.0  # the Normal Map's Strength
    uv_name: str | None = None  # the UV map the Normal Map (else a UV Map node) names; None the render UV map
    cutoff: float = -1.0  # alpha clip threshold; negative: none
    attribute: str | None = None  # the colour attribute an image is multiplied by

    def factors(self) -> tuple:
        """``factor`` as ``TextureMap.factor``: three floats."""
        return tuple(float(v) for v in np.broadcast_to(self.factor, 3))


def _followed(socket, label: str, normal: bool) -> _Chain:
    """The chain from ``socket`` (of the input ``label``; ``normal``: a Normal input) back through the nodes the
    engine carries along to the image, checker or colour attribute feeding it, or to constants; _Unsupported at a
    node it does not read."""
    chain = _Chain(_source(socket), normal)
    while chain.out is not None:
        node = chain.out.node
        if node.type in ("TEX_IMAGE", "TEX_CHECKER") or (_attribute(chain.out) is not None and chain.attribute is None):
            break
        _past(chain, node, label)
    return chain


def _past(chain: _Chain, node, label: str):
    """``chain`` moved past ``node``, one step toward its texture: a Normal Map's strength and UV map, a Separate
    Color's channel, a Multiply's factor (or colour attribute, ``_past_colour_multiply``), an alpha clip's cutoff."""
    if chain.normal and node.type == "NORMAL_MAP":
        s = _constant(node.inputs["Strength"])
        if node.space != "TANGENT" or s is None:
            raise _Unsupported(node, " (only tangent space with a constant Strength)")
        chain.strength, chain.uv_name, chain.normal = s, node.uv_map or None, False
        chain.out = _source(node.inputs["Color"])
    elif node.type in ("SEPARATE_COLOR", "SEPRGB") and getattr(node, "mode", "RGB") == "RGB" \
            and chain.out.name in CHANNELS and chain.channel < 0:
        chain.channel = CHANNELS[chain.out.name]
        chain.out = _source(node.inputs[0])
    elif node.type == "MIX" and node.data_type == "RGBA" and node.blend_type == "MULTIPLY" \
            and not node.clamp_result:
        _past_colour_multiply(chain, node)
    elif label == "Alpha" and chain.cutoff < 0 and (chain.factor == 1.0).all() and _threshold(node) is not None:
        chain.cutoff, chain.out = _threshold(node)
    elif node.type == "MATH" and node.operation == "MULTIPLY" and not node.use_clamp:
        linked = [s for s in node.inputs[:2] if _source(s) is not None]
        if len(linked) != 1:
            raise _Unsupported(node, " (only a Multiply of an image by a constant)")
        chain.factor = chain.factor * _constant(node.inputs[1] if _same(linked[0], node.inputs[0]) else node.inputs[0])
        chain.out = _source(linked[0])
    else:
        raise _Unsupported(node, "")


def _past_colour_multiply(chain: _Chain, node):
    """``chain`` moved past a Mix Color (Multiply): an image times a colour attribute (factor 1) takes the attribute
    along, one image or colour attribute times a constant colour that colour as a factor."""
    f, a, b = _constant(node.inputs[0]), node.inputs[6], node.inputs[7]
    linked = [s for s in (a, b) if _source(s) is not None]
    colours = [s for s in linked if _attribute(_source(s)) is not None]
    if f == 1.0 and len(linked) == 2 and colours and chain.attribute is None:  # image x colour attribute
        chain.attribute = _attribute(_source(colours[0]))
        chain.out = _source(b if _same(colours[0], a) else a)
        return
    if f is None or len(linked) != 1:
        raise _Unsupported(node, " (only a Multiply of one image or colour attribute by a constant colour, or of an "
                                 "image by a colour attribute)")
    other = np.array(_constant(b if _same(linked[0], a) else a)[:3])
    chain.factor = chain.factor * (1.0 - f + f * other)
    chain.out = _source(linked[0])


def _coordinates(node, chain: _Chain) -> tuple[np.ndarray, np.ndarray]:
    """(m, t) of texture ``node``'s lookup point p = m (u, v, 0) + t, from the UVs its Vector reads (the render UV
    map, a UV Map node's, which ``chain.uv_name`` takes where no Normal Map named one, or Texture Coordinate's UV)
    through a Mapping node; _Unsupported for other coordinates."""
    m, t, via = np.eye(3), np.zeros(3), _source(node.inputs["Vector"])
    if via is None and node.type == "TEX_CHECKER":
        raise _Unsupported(node, " at its default Generated coordinates (only UV coordinates)")
    if via is not None and via.node.type == "MAPPING":
        mapping = _mapping(via.node)
        if mapping is None:
            raise _Unsupported(via.node, " (only Point or Texture type with constant inputs)")
        (m, t), via = mapping, _source(via.node.inputs["Vector"])
    if via is not None:
        if via.node.type == "UVMAP" and not via.node.from_instancer:
            chain.uv_name = chain.uv_name or via.node.uv_map or None
        elif not (via.node.type == "TEX_COORD" and via.name == "UV"):
            raise _Unsupported(via.node, f" as the {node.bl_label}'s Vector (only UV coordinates)")
    return m, t


class MaterialTable:
    """Rows of every material met (``Materials.make``), in first-seen order, the images they read and the UV map
    each material's textures use (None: the render UV map)."""

    def __init__(self, warnings: list[str]):
        self.rows: list[dict] = []
        self.index: dict[str, int] = {}
        self.textures: list[np.ndarray] = []
        self.texture_index: dict[tuple[str, bool], int] = {}
        self.encoded: list[bool] = []  # per texture: its values sRGB-encoded (``TextureMap.srgb``)
        self.uv_map: dict[int, str | None] = {}
        self.images: dict[int, list[str]] = {}  # material id -> names of the images (and checker nodes) it reads
        self.color_attribute: dict[int, str] = {}  # material id -> the colour attribute it reads ('' the default)
        self.warnings = warnings
        self.holdouts: list[str] = []  # names of the materials rendering a Holdout shader (``unsupported`` warns)
        self._uv_names: list[str | None] = []  # of the material being read
        self._image_names: list[str] = []
        self._attributes: list[str] = []

    def id_of(self, material) -> int:
        if material is None:
            return 0
        key = material.name_full
        if key not in self.index:
            self._uv_names, self._image_names, self._attributes = [], [], []
            self.rows.append({**self._read(material), "pass_index": material.pass_index})
            self.index[key] = len(self.rows)
            names = sorted({n for n in self._uv_names if n is not None})  # None: the default map
            if len(names) > 1:
                self.warnings.append(f"material {material.name!r}: its textures use several UV maps "
                                     f"({', '.join(names)}); all read {names[0]!r}")
            self.uv_map[self.index[key]] = names[0] if names else None
            self.images[self.index[key]] = self._image_names
            attributes = sorted(set(self._attributes))
            if len(attributes) > 1:
                self.warnings.append(f"material {material.name!r}: it reads several colour attributes "
                                     f"({', '.join(a or 'the default' for a in attributes)}); all read "
                                     f"{attributes[0] or 'the default'!r}")
            if attributes:
                self.color_attribute[self.index[key]] = attributes[0]
        return self.index[key]

    def normal_mapped(self, material_id: int) -> bool:
        """Whether the material (or the second shader of its Mix Shader) reads a normal map."""
        if material_id <= 0:
            return False
        row = self.rows[material_id - 1]
        return "normal" in row.get("maps", {}) or self.normal_mapped(row.get("mix_other", 0))

    def build(self) -> Materials:
        return Materials.make(self.rows)

    def _image(self, image, material, alpha: bool) -> int | None:
        key = (image.name_full, alpha)
        if key not in self.texture_index:
            pixels = image_pixels(image, alpha, encoded=True)
            if pixels is None:
                self.warnings.append(f"material {material.name!r}: image {image.name!r} could not be loaded "
                                     f"({image.filepath or 'no file'}); using the input's value instead")
                self.texture_index[key] = -1
            else:
                self._texture(key, pixels, stored_as_srgb(image))
        index = self.texture_index[key]
        return None if index < 0 else index

    def _texture(self, key: tuple, pixels: np.ndarray, encoded: bool = False) -> int:
        """The index of the texture ``key`` names, ``pixels`` added the first time."""
        if key not in self.texture_index:
            self.textures.append(pixels)
            self.encoded.append(encoded)
            self.texture_index[key] = len(self.textures) - 1
        return self.texture_index[key]

    def _map(self, material, label: str, socket, normal: bool = False) -> TextureMap | None:
        """The TextureMap feeding ``socket`` (None with a warning when the chain is not one the engine reads)."""
        try:
            chain = _followed(socket, label, normal)
            if chain.out is None:
                return None  # a chain of constants: the input's value stands
            return self._texture_map(material, chain)
        except _Unsupported as unread:
            node, why = unread.args
            self.warnings.append(f"material {material.name!r}: {label} from {node.bl_label!r} ({node.name}) is not "
                                 f"supported{why}; using the input's value")
            return None

    def _texture_map(self, material, chain: _Chain) -> TextureMap | None:
        """The TextureMap of a chain (``_followed``) that ends at an image, a checker or a colour attribute; None
        for an Image Texture without an image or one that does not load."""
        out, node = chain.out, chain.out.node
        if chain.normal:
            raise _Unsupported(node, " without a Normal Map node")
        if node.type not in ("TEX_IMAGE", "TEX_CHECKER"):  # a colour attribute alone
            self._attributes.append(_attribute(out))
            return TextureMap(-1, chain.channel, chain.factors(), vertex=True)
        if node.type == "TEX_IMAGE" and node.image is None:
            return None
        if node.type == "TEX_IMAGE" and node.projection != "FLAT":
            raise _Unsupported(node, f" with {node.projection.lower()} projection")
        if out.name == "Alpha":
            if chain.channel >= 0:
                raise _Unsupported(node, " (a channel of its alpha)")
            chain.channel = 3
        m, t = _coordinates(node, chain)
        if node.type == "TEX_CHECKER":
            texture = self._checker_texture(node, m, t, fac=out.name != "Color")  # Fac (Factor in Blender 5)
        else:
            texture = self._image_texture(material, node, m, t, alpha=chain.channel == 3)
        if texture is None:
            return None
        index, uv, extension, closest, srgb = texture
        self._uv_names.append(chain.uv_name)
        if chain.attribute is not None:
            self._attributes.append(chain.attribute)
        return TextureMap(index, chain.channel, chain.factors(), tuple(float(v) for v in uv), extension, closest,
                          float(chain.strength), float(chain.cutoff), vertex=chain.attribute is not None, srgb=srgb)

    def _checker_texture(self, node, m: np.ndarray, t: np.ndarray, fac: bool) -> tuple:
        """(texture index, UV transform, extension, closest, sRGB) of a Checker Texture at p = m (u, v, 0) + t: its
        2x2 texel image (``_checker``), read Closest and Repeat."""
        checker = _checker(node, m, t, fac)
        if checker is None:
            raise _Unsupported(node, " (only constant colours and scale, on UVs mapped within their plane)")
        texels, uv = checker
        index = self._texture(("checker", texels.tobytes()), texels)
        self._image_names.append(node.name)
        return index, uv, "REPEAT", True, False

    def _image_texture(self, material, node, m: np.ndarray, t: np.ndarray, alpha: bool) -> tuple | None:
        """(texture index, UV transform, extension, closest, sRGB) of an Image Texture at p = m (u, v, 0) + t (an
        extension the engine does not read as Repeat, with a warning); None when its image does not load."""
        extension = node.extension if node.extension in ("REPEAT", "EXTEND", "CLIP") else "REPEAT"
        if extension != node.extension:
            self.warnings.append(f"material {material.name!r}: image {node.image.name!r} extension "
                                 f"{node.extension.title()} is read as Repeat")
        index = self._image(node.image, material, alpha=alpha)
        if index is None:
            return None
        uv = (m[0, 0], m[0, 1], t[0], m[1, 0], m[1, 1], t[1])
        closest, srgb = node.interpolation == "Closest", self.encoded[index]
        self._image_names.append(node.image.name)
        return index, uv, extension, closest, srgb

    def _read(self, material) -> dict:
        row = {"name": material.name}
        surface = output_shader(material)
        if surface is None:
            row["base_color"] = tuple(material.diffuse_color)[:3]
            row["roughness"] = material.roughness
            row["metallic"] = material.metallic
            return row
        return self._shader(material, surface, row)

    def _shader(self, material, surface, row: dict) -> dict:
        """``row`` filled from the shader node ``surface`` (following Mix and Add Shaders)."""
        if surface.type == "BSDF_PRINCIPLED":
            return self._principled(material, surface, row)
        if surface.type == "EMISSION":
            strength = _value(surface.inputs["Strength"])
            row["base_color"] = (0.0, 0.0, 0.0)
            row["emission"] = tuple(c * strength for c in _value(surface.inputs["Color"])[:3])
            self._linked(material, row, surface, {"Color": "emission"}, scale=strength)
            return row
        if surface.type == "BSDF_GLASS":
            row["base_color"] = _value(surface.inputs["Color"])[:3]
            row["roughness"] = _value(surface.inputs["Roughness"])
            row["ior"] = _value(surface.inputs["IOR"])
            row["transmission"], row["specular"] = 1.0, 0.5
            for name in ("Color", "Roughness", "IOR"):
                if _source(surface.inputs[name]) is not None:
                    self.warnings.append(f"material {material.name!r}: linked {name!r} of the Glass BSDF is not "
                                         f"supported; using its value")
            return row
        if surface.type == "BSDF_DIFFUSE":
            row["base_color"] = _value(surface.inputs["Color"])[:3]
            row["roughness"] = 1.0
            self._linked(material, row, surface, {"Color": "base_color"})
            self._normal(material, row, surface)
            return row
        if surface.type == "BSDF_GLOSSY":
            return self._glossy(material, surface, row)
        if surface.type == "HOLDOUT":  # Cycles: a hole for the camera, a black absorber for every other ray
            self.holdouts.append(material.name)
            row["base_color"] = (0.0, 0.0, 0.0)
            return row
        if surface.type == "MIX_SHADER":
            return self._mix(material, surface, row)
        if surface.type == "ADD_SHADER":
            return self._add(material, surface, row)
        self.warnings.append(f"material {material.name!r}: surface shader {surface.bl_label!r} is not supported; "
                             f"rendered as grey diffuse")
        return {"name": material.name}

    def _glossy(self, material, node, row: dict) -> dict:
        """The Glossy BSDF as the metallic lobe (GGX, its roughness), with the F82 tint that gives its Fresnel the
        mean reflectance Color (``microfacet.constant_reflectance_tint``): Cycles' Glossy BSDF has no Fresnel. A
        textured Color keeps the tint of its unlinked value (the tint is one value per material)."""
        colour = np.clip(np.array(_value(node.inputs["Color"])[:3]), 0.0, 1.0)
        tint = constant_reflectance_tint(colour)
        row.update(base_color=tuple(colour), roughness=_value(node.inputs["Roughness"]), metallic=1.0,
                   specular_tint=tuple(tint))
        if _constant(node.inputs["Anisotropy"]) != 0.0:
            self.warnings.append(f"material {material.name!r}: the anisotropy of {node.bl_label!r} ({node.name}) "
                                 f"is not supported; rendered isotropic")
        self._linked(material, row, node, {"Color": "base_color", "Roughness": "roughness"})
        self._normal(material, row, node)
        return row

    def _mix(self, material, node, row: dict) -> dict:
        """A Mix Shader with a Transparent BSDF on one side is the other shader with an alpha cut-out (the factor,
        or one minus it, a constant or a map; how older glTF imports and leaf assets cut out); between two other
        shaders, the one with the larger constant weight stands for both, with a warning."""
        fac, first, second = node.inputs[0], _source(node.inputs[1]), _source(node.inputs[2])
        shaders = [None if s is None else s.node for s in (first, second)]
        transparent = [s is not None and s.type == "BSDF_TRANSPARENT" for s in shaders]
        if transparent[0] != transparent[1]:
            kept = shaders[1] if transparent[0] else shaders[0]
            tint = shaders[0] if transparent[0] else shaders[1]
            if (_constant(tint.inputs["Color"]) or (0.0,))[:3] != (1.0, 1.0, 1.0):
                self.warnings.append(f"material {material.name!r}: the Transparent BSDF's colour in {node.name!r} "
                                     f"is read as white")
            row = {"name": row["name"], "base_color": (0.0, 0.0, 0.0)} if kept is None \
                else self._shader(material, kept, row)
            value = _constant(fac)
            if value is not None:  # fac is the second shader's weight
                opacity = value if transparent[0] else 1.0 - value
                row["alpha"] = row.get("alpha", 1.0) * float(np.clip(opacity, 0.0, 1.0))
                return row
            if not transparent[0]:
                self.warnings.append(f"material {material.name!r}: Mix Shader {node.name!r} with the Transparent "
                                     f"BSDF second and a linked factor (opacity 1 - factor) is not supported; opaque")
                return row
            tmap = self._map(material, "Alpha", fac)
            if tmap is not None:
                row.setdefault("maps", {})["alpha"] = tmap
            return row
        if sorted(str(getattr(s, "type", None)) for s in shaders) == ["BSDF_DIFFUSE", "BSDF_GLOSSY"]:
            mixed = self._diffuse_and_glossy(material, fac, shaders, row)
            if mixed is not None:
                return mixed
        value = _constant(fac)
        if None not in shaders and (value is None or 0.0 < value < 1.0):
            mixed = self._blended(material, node, fac, value, shaders, row)
            if mixed is not None:
                return mixed
        weight = 0.5 if value is None else float(np.clip(value, 0.0, 1.0))
        kept = shaders[1] if weight > 0.5 else shaders[0]
        if kept is None:
            self.warnings.append(f"material {material.name!r}: Mix Shader {node.name!r} has no shader on its "
                                 f"heavier side; rendered as grey diffuse")
            return {"name": row["name"]}
        if 0.0 < weight < 1.0:
            self.warnings.append(f"material {material.name!r}: Mix Shader {node.name!r} is rendered as its "
                                 f"{'second' if weight > 0.5 else 'first'} shader {kept.bl_label!r} alone "
                                 f"(factor {'linked' if value is None else f'{value:g}'})")
        return self._shader(material, kept, row)

    def _blended(self, material, node, fac, value, shaders, row: dict) -> dict | None:
        """A Mix Shader of two opaque shaders that neither glow nor mix further, by a constant factor or an image
        (a mask): the first shader's row, blended at each point with a row of the second (appended to the table,
        ``Materials.mix_other``) by the factor (``surface._blend``). None (and no trace of having read the two
        shaders) when a side is not such a shader. A factor from a chain the engine does not read takes the
        factor's own value (with ``_map``'s warning)."""
        mask, warned, held, rows = None, len(self.warnings), len(self.holdouts), len(self.rows)
        if value is None:
            value, mask = self._mask(material, fac)
        first = self._shader(material, shaders[0], {"name": row["name"]})
        second = self._shader(material, shaders[1], {"name": f"{row['name']} ({node.name}: second shader)"})
        if not (_plain(first) and _plain(second)):  # a side that mixes in turn has added its second row: gone
            del self.warnings[warned:], self.holdouts[held:], self.rows[rows:]
            return None
        self.rows.append(second)
        first["mix_other"], first["mix_factor"] = len(self.rows), value
        if mask is not None:
            first.setdefault("maps", {})["mix"] = mask
        return first

    def _mask(self, material, fac) -> tuple[float, TextureMap | None]:
        """(the weight, its map) of a Mix Shader's linked factor ``fac``: an image (a mask) is the map, of weight
        1; a chain the engine does not read leaves the factor's own value, with ``_map``'s warning."""
        mask = self._map(material, "Fac", fac)
        return (1.0, mask) if mask is not None else (float(np.clip(_value(fac), 0.0, 1.0)), None)

    def _diffuse_and_glossy(self, material, fac, shaders, row: dict) -> dict | None:
        """A Mix Shader of a Diffuse and a Glossy BSDF as one material, or None for a factor it does not read: the
        Diffuse's colour (and maps, normal) with a metallic lobe of the Glossy's colour (``Materials.metal_color``,
        with the tint that gives its Fresnel that mean, as ``_glossy``) and roughness, weighted by the constant
        factor f (the second shader's weight), which is Cycles' (1 - f) Diffuse + f Glossy, or into the Glossy's side
        by an image (a mask: the metallic lobe's map) or at each point by the Fresnel curve of a Fresnel node's Fac
        or a Layer Weight's Fresnel (IOR 1 / (1 - Blend), as Cycles computes it; ``Materials.fresnel_mix``: F(N . I)
        as Cycles' mix). (A Principled dielectric layer of that IOR instead is 20 % brighter than Cycles' mix at
        grazing views, as Cycles' own Principled BSDF is.)"""
        glossy_second = shaders[1].type == "BSDF_GLOSSY"
        diffuse, glossy = (shaders[0], shaders[1]) if glossy_second else (shaders[1], shaders[0])
        value, ior, mask = _constant(fac), None, None
        if value is None:
            if not glossy_second:
                return None
            ior = _fresnel_ior(fac)
            if ior is None:  # an image (a mask) weighs the Glossy: the metallic lobe's map
                value, mask = self._mask(material, fac)
        gloss = self._glossy(material, glossy, {"name": row["name"]})
        row = self._shader(material, diffuse, row)
        row["roughness"] = gloss["roughness"]
        maps = gloss.get("maps", {})
        if "roughness" in maps:
            row.setdefault("maps", {})["roughness"] = maps["roughness"]
        if "base_color" in maps:
            self.warnings.append(f"material {material.name!r}: the linked Color of {glossy.bl_label!r} "
                                 f"({glossy.name}) mixed with a Diffuse BSDF is read as its value")
        row["metal_color"], row["specular_tint"] = gloss["base_color"], gloss["specular_tint"]
        if ior is None:
            weight = float(np.clip(value, 0.0, 1.0))
            row["metallic"] = weight if glossy_second else 1.0 - weight
        else:
            row["metallic"], row["fresnel_mix"] = 0.0, ior
        if mask is not None:
            row.setdefault("maps", {})["metallic"] = mask
        return row

    def _add(self, material, node, row: dict) -> dict:
        """An Add Shader of an Emission shader and a surface is that surface glowing (its emission added); two
        other shaders: the first stands for both, with a warning."""
        shaders = [None if s is None else s.node for s in (_source(node.inputs[0]), _source(node.inputs[1]))]
        glowing = [s is not None and s.type == "EMISSION" for s in shaders]
        if glowing[0] != glowing[1]:
            emitter, surface = (shaders[0], shaders[1]) if glowing[0] else (shaders[1], shaders[0])
            row = {"name": row["name"], "base_color": (0.0, 0.0, 0.0)} if surface is None \
                else self._shader(material, surface, row)
            glow = self._shader(material, emitter, {"name": row["name"]})
            if "emission" in row.get("maps", {}) and "emission" in glow.get("maps", {}):
                self.warnings.append(f"material {material.name!r}: two emission maps meet in {node.name!r}; the "
                                     f"Emission shader's is used")
            row["emission"] = tuple(a + b for a, b in zip(row.get("emission", (0.0, 0.0, 0.0)), glow["emission"]))
            if "emission" in glow.get("maps", {}):
                row.setdefault("maps", {})["emission"] = glow["maps"]["emission"]
            return row
        self.warnings.append(f"material {material.name!r}: Add Shader {node.name!r} is rendered as its first shader")
        return self._shader(material, shaders[0], row) if shaders[0] is not None else {"name": row["name"]}

    def _principled(self, material, node, row: dict) -> dict:
        inputs = node.inputs
        row["base_color"] = _value(inputs["Base Color"])[:3]
        row["roughness"] = _value(inputs["Roughness"])
        row["metallic"] = _value(inputs["Metallic"])
        row["specular_tint"] = _value(inputs["Specular Tint"])[:3]
        row["ior"] = _value(inputs["IOR"])
        row["specular"] = _value(inputs["Specular IOR Level"])
        row["alpha"] = _value(inputs["Alpha"])
        row["transmission"] = _value(inputs["Transmission Weight"])
        if 0.0 < row["transmission"] < 1.0:
            self.warnings.append(f"material {material.name!r}: Transmission Weight {row['transmission']:g} is read "
                                 f"as {'glass' if row['transmission'] >= 0.5 else 'opaque'}")
        if row["transmission"] >= 0.5 and row["metallic"] < 0.5:  # glass: the colour of one crossing
            row["base_color"] = tuple(float(np.sqrt(np.clip(c, 0.0, 1.0))) for c in row["base_color"])
        strength = _value(inputs["Emission Strength"])
        row["emission"] = tuple(c * strength for c in _value(inputs["Emission Color"])[:3])
        self._linked(material, row, node, {"Base Color": "base_color", "Roughness": "roughness",
                                           "Metallic": "metallic", "Emission Color": "emission", "Alpha": "alpha"},
                     scale=strength)
        self._normal(material, row, node)
        for name in ("Specular Tint", "IOR", "Specular IOR Level", "Emission Strength", "Transmission Weight"):
            if _source(inputs[name]) is not None:
                self.warnings.append(f"material {material.name!r}: linked {name!r} is not supported; using its value")
        for name in UNRENDERED_LAYERS:
            value = _constant(inputs[name]) if name in inputs else 0.0
            if value != 0.0:
                self.warnings.append(f"material {material.name!r}: {node.bl_label!r} {name} "
                                     f"{'is linked' if value is None else f'{value:g}'}: not rendered (that layer "
                                     f"is not supported yet)")
        return row

    def _normal(self, material, row: dict, node):
        """A normal map or a Bump node (and a normal map on the Bump node's Normal) on ``node``'s Normal input."""
        source = _source(node.inputs["Normal"])
        if source is not None and source.node.type == "BUMP":
            node = source.node
            self._bump(material, row, node)
        if _source(node.inputs["Normal"]) is not None:
            tmap = self._map(material, "Normal", node.inputs["Normal"], normal=True)
            if tmap is not None:
                row.setdefault("maps", {})["normal"] = tmap

    def _bump(self, material, row: dict, node):
        """A Bump node's height map, its Distance (negated by Invert) folded into the map's factor and its Strength
        kept as the map's strength."""
        strength, distance = _constant(node.inputs["Strength"]), _constant(node.inputs["Distance"])
        if strength is None or distance is None:
            self.warnings.append(f"material {material.name!r}: Bump {node.name!r} with a linked Strength or "
                                 f"Distance is not supported; no bump")
            return
        if _source(node.inputs["Height"]) is None:
            return  # a constant height: a flat bump
        tmap = self._map(material, "Height", node.inputs["Height"])
        if tmap is None:
            return
        if tmap.image < 0:
            self.warnings.append(f"material {material.name!r}: Bump {node.name!r} with a colour attribute as its "
                                 f"Height is not supported; no bump")
            return
        scale = -distance if node.invert else distance
        row.setdefault("maps", {})["bump"] = replace(tmap, factor=tuple(f * scale for f in tmap.factor),
                                                     strength=float(strength))

    def _linked(self, material, row: dict, node, inputs: dict[str, str], scale: float = 1.0):
        """Texture maps for the linked ``inputs`` of ``node`` (socket name -> engine input)."""
        for socket_name, name in inputs.items():
            socket = node.inputs[socket_name]
            if _source(socket) is None:
                continue
            tmap = self._map(material, socket_name, socket)
            if tmap is None:
                continue
            if name == "emission":  # Emission Color x Strength
                tmap = replace(tmap, factor=tuple(f * scale for f in tmap.factor))
            row.setdefault("maps", {})[name] = tmap
