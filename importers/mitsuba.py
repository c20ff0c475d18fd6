"""Mitsuba scene XML (versions 0.6 to 3) -> plain data: camera, shapes, materials, emitters, environment.

No bpy here (``shared_scenes`` builds the Blender scene from what this returns), so every rule of the mapping is
unit-testable from a small XML string. Coordinates stay Mitsuba's (Y up; the camera looks along its local +Z with +X to
the image's left); the builder turns them into Blender's frame.

What cannot be represented exactly is approximated, and each approximation adds one warning that starts with the XML
element it comes from, e.g. ``bsdf id="Metal" type="roughconductor": approximated as ...``.
"""
from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

DEFAULT_WIDTH = 256


@dataclass
class Texture:
    kind: str  # "bitmap" or "checkerboard"
    filename: str = ""  # absolute path of a bitmap
    color0: tuple = (0.4, 0.4, 0.4)  # checkerboard colours (Mitsuba's defaults)
    color1: tuple = (0.2, 0.2, 0.2)
    uv_scale: tuple = (1.0, 1.0)  # to_uv scale of a checkerboard (cells of half a period)
    element: str = ""  # the XML element, for messages


@dataclass
class Material:
    """A Principled BSDF's settings (Blender names), from one Mitsuba BSDF."""
    name: str
    base_color: tuple = (0.5, 0.5, 0.5)
    texture: Texture | None = None
    roughness: float = 1.0
    metallic: float = 0.0
    specular: float = 0.0  # Principled "Specular IOR Level": 0 for a pure diffuse, 0.5 for IOR 1.5
    transmission: float = 0.0
    ior: float = 1.5


@dataclass
class Shape:
    element: str  # the XML element, for messages
    kind: str  # obj, rectangle, cube, sphere, disk, polygons
    matrix: np.ndarray  # 4x4 to_world (Mitsuba frame)
    material: Material
    filename: str = ""
    face_normals: bool = False
    radiance: np.ndarray | None = None  # area emitter on this shape (W/(m^2 sr))
    name: str = ""
    polygons: tuple | None = None  # kind "polygons": (vertices (N,3), list of vertex-index lists), in place of a file


@dataclass
class PointLight:
    element: str
    position: np.ndarray
    intensity: np.ndarray  # W/sr


@dataclass
class SpotLight:
    element: str
    matrix: np.ndarray  # to_world; the spot shines along local +Z
    intensity: np.ndarray  # W/sr on the axis
    cutoff_deg: float
    beam_width_deg: float


@dataclass
class Environment:
    kind: str  # "envmap" or "constant"
    radiance: np.ndarray = field(default_factory=lambda: np.zeros(3))
    filename: str = ""
    matrix: np.ndarray = field(default_factory=lambda: np.eye(4))
    scale: float = 1.0
    element: str = "emitter"


@dataclass
class Camera:
    matrix: np.ndarray  # to_world: looks along local +Z, +Y up, +X to the image's left
    fov_deg: float
    fov_axis: str  # x, y, diagonal, smaller, larger
    width: int  # already scaled to the requested width
    height: int
    source_size: tuple  # (width, height) in the XML
    near: float = 1e-2
    far: float = 1e4
    element: str = "sensor"


@dataclass
class MitsubaScene:
    path: str
    camera: Camera | None
    shapes: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    environment: Environment | None = None
    max_bounces: int | None = None
    warnings: list = field(default_factory=list)


class MitsubaError(ValueError):
    """The file cannot be converted at all (not XML, not a Mitsuba scene)."""


def element_name(el: ET.Element) -> str:
    """``bsdf id="Metal" type="roughconductor"``: how a warning names the element it is about."""
    parts = [el.tag]
    for key in ("id", "name", "type"):
        if key in el.attrib:
            parts.append(f'{key}="{el.attrib[key]}"')
    if el.tag == "shape":
        fn = el.find("string[@name='filename']")
        if fn is not None:
            parts.append(f'filename="{fn.get("value")}"')
    return " ".join(parts)


# --- values --------------------------------------------------------------------------------------------------------

def _numbers(text: str) -> list[float]:
    return [float(t) for t in re.split(r"[,\s]+", text.strip()) if t]


def _wyman_cie(wl: np.ndarray) -> np.ndarray:
    """CIE 1931 colour matching functions, multi-lobe Gaussian fit of Wyman, Sloan and Shirley (JCGT 2013)."""
    def g(x, mu, s1, s2):
        s = np.where(x < mu, s1, s2)
        return np.exp(-0.5 * ((x - mu) / s) ** 2)
    x = 1.056 * g(wl, 599.8, 37.9, 31.0) + 0.362 * g(wl, 442.0, 16.0, 26.7) - 0.065 * g(wl, 501.1, 20.4, 26.2)
    y = 0.821 * g(wl, 568.8, 46.9, 40.5) + 0.286 * g(wl, 530.9, 16.3, 31.1)
    z = 1.217 * g(wl, 437.0, 11.8, 36.0) + 0.681 * g(wl, 459.0, 26.0, 13.8)
    return np.stack([x, y, z], axis=-1)


XYZ_TO_LINEAR_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                               [-0.9692660, 1.8760108, 0.0415560],
                               [0.0556434, -0.2040259, 1.0572252]])


def spectrum_to_rgb(wavelengths, values) -> np.ndarray:
    """Linear sRGB of a sampled spectrum (piecewise linear, zero outside its range), scaled so that a constant
    spectrum c gives (c, c, c) (equal-energy white maps to white)."""
    wl = np.asarray(wavelengths, np.float64)
    v = np.asarray(values, np.float64)
    grid = np.arange(360.0, 831.0, 1.0)
    s = np.interp(grid, wl, v, left=0.0, right=0.0)
    if len(wl) == 1:
        s = np.full_like(grid, v[0])
    cmf = _wyman_cie(grid)
    rgb = XYZ_TO_LINEAR_SRGB @ (s @ cmf)
    white = XYZ_TO_LINEAR_SRGB @ cmf.sum(axis=0)
    return rgb / white


def _spectrum(el: ET.Element) -> np.ndarray:
    text = el.get("value", "")
    if ":" not in text:
        n = _numbers(text)
        return np.array(n * 3 if len(n) == 1 else n[:3], np.float64)
    pairs = [p.split(":") for p in re.split(r"[,\s]+", text.strip()) if p]
    wl, val = zip(*((float(a), float(b)) for a, b in pairs))
    return spectrum_to_rgb(wl, val)


def _rgb(el: ET.Element) -> np.ndarray:
    if el.tag == "spectrum":
        return _spectrum(el)
    n = _numbers(el.get("value", "0"))
    return np.array(n * 3 if len(n) == 1 else n[:3], np.float64)


def _vector(el: ET.Element, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    if "value" in el.attrib:
        n = _numbers(el.get("value"))
        return np.array(n * 3 if len(n) == 1 else n[:3], np.float64)
    return np.array([float(el.get(k, d)) for k, d in zip("xyz", default)], np.float64)


def _rotation(axis, degrees) -> np.ndarray:
    a = np.asarray(axis, np.float64)
    a = a / np.linalg.norm(a)
    t = math.radians(degrees)
    c, s = math.cos(t), math.sin(t)
    x, y, z = a
    r = np.array([[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
                  [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
                  [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]])
    m = np.eye(4)
    m[:3, :3] = r
    return m


def look_at(origin, target, up) -> np.ndarray:
    """Mitsuba's lookat: columns (left, up, forward, origin); the camera looks along +Z."""
    o, t, u = (np.asarray(v, np.float64) for v in (origin, target, up))
    d = t - o
    d /= np.linalg.norm(d)
    left = np.cross(u, d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, o
    return m


def parse_transform(el: ET.Element, warnings: list) -> np.ndarray:
    """A ``<transform>``: each child is applied after the ones before it (left-multiplied)."""
    m = np.eye(4)
    for child in el:
        step = np.eye(4)
        if child.tag == "matrix":
            step = np.array(_numbers(child.get("value")), np.float64).reshape(4, 4)
        elif child.tag == "translate":
            step[:3, 3] = _vector(child)
        elif child.tag == "scale":
            if "value" in child.attrib:
                n = _numbers(child.get("value"))
                s = n * 3 if len(n) == 1 else n[:3]
            else:
                s = [float(child.get(k, 1.0)) for k in "xyz"]
            step = np.diag([*s, 1.0])
        elif child.tag == "rotate":
            axis = _vector(child, (0.0, 0.0, 0.0)) if "value" in child.attrib else \
                np.array([float(child.get(k, 0.0)) for k in "xyz"])
            step = _rotation(axis, float(child.get("angle", 0.0)))
        elif child.tag == "lookat":
            step = look_at(_numbers(child.get("origin")), _numbers(child.get("target")),
                           _numbers(child.get("up", "0 1 0")))
        else:
            warnings.append(f"{element_name(child)} in {element_name(el)}: unknown transform step; ignored")
            continue
        m = step @ m
    return m


# --- the scene -----------------------------------------------------------------------------------------------------

class _Parser:
    def __init__(self, path: str, width: int):
        self.path = path
        self.folder = os.path.dirname(os.path.abspath(path))
        self.width = width
        self.warnings: list[str] = []
        self.ids: dict[str, ET.Element] = {}
        self.materials: dict[int, Material] = {}
        self.defaults: dict[str, str] = {}

    def warn(self, el: ET.Element, message: str) -> None:
        self.warnings.append(f"{element_name(el)}: {message}")

    # properties of an element, by name
    def prop(self, el, name, default=None):
        for child in el:
            if child.get("name") == name:
                if child.tag in ("float", "integer"):
                    return float(child.get("value"))
                if child.tag == "boolean":
                    return child.get("value", "false").strip().lower() == "true"
                if child.tag == "string":
                    return child.get("value")
                if child.tag in ("rgb", "spectrum"):
                    return _rgb(child)
                if child.tag in ("vector", "point"):
                    return _vector(child)
                if child.tag == "transform":
                    return parse_transform(child, self.warnings)
                return child
        return default

    def resolve(self, el):
        if el.tag == "ref":
            target = self.ids.get(el.get("id"))
            if target is None:
                raise MitsubaError(f"{element_name(el)}: no element with this id in {self.path}")
            return target
        return el

    def substitute(self, root) -> None:
        for el in root.iter():
            if el.tag == "default":
                self.defaults[el.get("name")] = el.get("value")
        if not self.defaults:
            return
        for el in root.iter():
            for key, value in el.attrib.items():
                if "$" in value:
                    el.set(key, re.sub(r"\$(\w+)", lambda m: self.defaults.get(m.group(1), m.group(0)), value))

    # --- materials
    def texture(self, el, owner) -> Texture | None:
        el = self.resolve(el)
        kind = el.get("type")
        if kind == "bitmap":
            fn = self.prop(el, "filename", "")
            return Texture("bitmap", filename=os.path.join(self.folder, fn), element=element_name(el))
        if kind == "checkerboard":
            uv = self.prop(el, "to_uv")
            scale = (float(np.linalg.norm(uv[:3, 0])), float(np.linalg.norm(uv[:3, 1]))) if uv is not None else (1, 1)
            c0 = self.prop(el, "color0", np.array([0.4] * 3))
            c1 = self.prop(el, "color1", np.array([0.2] * 3))
            return Texture("checkerboard", color0=tuple(c0), color1=tuple(c1), uv_scale=scale,
                           element=element_name(el))
        self.warn(el, f"texture of {element_name(owner)} is not supported; using grey 0.5")
        return None

    def colour(self, el, name, default):
        """(rgb, texture) of a reflectance property that may be a value or a texture."""
        for child in el:
            if child.get("name") == name:
                if child.tag in ("texture", "ref"):
                    tex = self.texture(child, el)
                    if tex is None:
                        return np.array([0.5] * 3), None
                    mean = np.mean([tex.color0, tex.color1], axis=0) if tex.kind == "checkerboard" else [0.5] * 3
                    return np.asarray(mean, np.float64), tex
                return _rgb(child), None
        return np.array(default, np.float64), None

    def material(self, el) -> Material:
        el = self.resolve(el)
        key = id(el)
        if key not in self.materials:
            name = el.get("id") or f"{el.get('type')}_{len(self.materials)}"
            self.materials[key] = self._material(el, name)
        return self.materials[key]

    def _material(self, el, name, outer: str = "") -> Material:
        """``outer`` names the wrapping elements (twosided, bumpmap) so a warning about an inner BSDF without an
        id still says which material it is."""
        kind = el.get("type")
        here = f"{outer} > {element_name(el)}" if outer else element_name(el)

        def warn(message):
            self.warnings.append(f"{here}: {message}")

        if kind == "twosided":
            inner = [c for c in el if c.tag in ("bsdf", "ref")]
            if not inner:
                warn("no inner BSDF; grey diffuse")
                return Material(name)
            if len(inner) > 1:
                warn("a different BSDF on the back side is not supported; using the front one on both")
            return self._material(self.resolve(inner[0]), name, here)
        if kind in ("bumpmap", "normalmap", "mask"):
            inner = [c for c in el if c.tag in ("bsdf", "ref")]
            what = {"bumpmap": "bump map", "normalmap": "normal map", "mask": "opacity mask"}[kind]
            warn(f"{what} is not supported; using the inner BSDF alone")
            return self._material(self.resolve(inner[0]), name, here) if inner else Material(name)
        if kind == "diffuse":
            rgb, tex = self.colour(el, "reflectance", (0.5, 0.5, 0.5))
            return Material(name, tuple(rgb), tex)
        alpha = self.prop(el, "alpha", None)
        if alpha is None:
            au, av = self.prop(el, "alpha_u", None), self.prop(el, "alpha_v", None)
            alpha = math.sqrt(au * av) if au is not None and av is not None else None
        rough = math.sqrt(max(alpha, 0.0)) if alpha is not None else (0.1 if kind.startswith("rough") else 0.0)
        if kind in ("plastic", "roughplastic"):
            rgb, tex = self.colour(el, "diffuse_reflectance", (0.5, 0.5, 0.5))
            ior = self._ior(el)
            warn(f"approximated as Principled BSDF: base colour = diffuse_reflectance, roughness "
                 f"{rough:.3f} (sqrt alpha), specular IOR {ior:.2f}")
            return Material(name, tuple(rgb), tex, roughness=rough, specular=0.5, ior=ior)
        if kind in ("conductor", "roughconductor"):
            spec, tex = self.colour(el, "specular_reflectance", (1.0, 1.0, 1.0))
            eta, k = self.prop(el, "eta"), self.prop(el, "k")
            mat_name = self.prop(el, "material", None)
            if eta is not None and k is not None:
                f0 = ((eta - 1) ** 2 + k ** 2) / ((eta + 1) ** 2 + k ** 2)
                how = "base colour = normal-incidence Fresnel of eta, k x specular_reflectance"
            elif mat_name == "none":
                f0, how = np.ones(3), "a perfect mirror (material none): base colour = specular_reflectance"
            else:
                f0 = np.array([0.95, 0.64, 0.54]) if mat_name in (None, "Cu") else np.array([0.9, 0.9, 0.9])
                how = f"base colour = a fixed metal colour for material {mat_name or 'Cu (default)'}"
            warn(f"approximated as metallic Principled BSDF: {how}, roughness {rough:.3f} (sqrt alpha)")
            if tex is not None and tex.kind == "checkerboard":
                tex = Texture("checkerboard", color0=tuple(np.asarray(tex.color0) * f0),
                              color1=tuple(np.asarray(tex.color1) * f0), uv_scale=tex.uv_scale, element=tex.element)
            return Material(name, tuple(np.clip(spec * f0, 0, 1)), tex, roughness=rough, metallic=1.0, specular=0.5)
        if kind in ("dielectric", "roughdielectric", "thindielectric"):
            ior = self._ior(el)
            warn(f"approximated as Principled BSDF transmission 1, IOR {ior:.2f}, roughness {rough:.3f}")
            return Material(name, (1.0, 1.0, 1.0), roughness=rough, transmission=1.0, specular=0.5, ior=ior)
        warn("BSDF type is not supported; rendered as grey diffuse 0.5")
        return Material(name)

    def _ior(self, el) -> float:
        def value(n, default):
            v = self.prop(el, n, default)
            if isinstance(v, str):
                return {"air": 1.000277, "water": 1.333, "bk7": 1.5046, "polypropylene": 1.49,
                        "acrylic glass": 1.49}.get(v.lower(), default)
            return float(v)
        return value("int_ior", 1.49) / value("ext_ior", 1.000277)

    # --- shapes
    def shapes(self, el, parent: np.ndarray, out: list) -> None:
        kind = el.get("type")
        if kind == "shapegroup":
            return  # only reached through an instance
        matrix = self.prop(el, "to_world", None)
        if matrix is None:
            matrix = self.prop(el, "toWorld", None)
        if kind == "instance":
            group = next((self.resolve(c) for c in el if c.tag == "ref"), None)
            if matrix is None:
                bounds = self.prop(el, "min_bounds", None)
                matrix = np.eye(4)
                if bounds is not None:  # active-exploration's randomised instance: its parameters at 0
                    matrix[:3, 3] = bounds
                    self.warn(el, f"randomised instance (active-exploration): placed at min_bounds "
                                  f"{tuple(round(float(b), 4) for b in bounds)}, no rotation (the pose the meshes "
                                  f"were modelled in)")
            if group is None:
                self.warn(el, "instance without a shapegroup reference; skipped")
                return
            for child in group:
                if child.tag == "shape":
                    self.shapes(child, parent @ matrix, out)
            return
        matrix = parent @ (matrix if matrix is not None else np.eye(4))
        if kind not in ("obj", "rectangle", "cube", "sphere", "disk", "ply", "serialized"):
            self.warn(el, "shape type is not supported; skipped")
            return
        if kind in ("ply", "serialized"):
            self.warn(el, f"{kind} meshes are not supported (only obj); skipped")
            return
        filename = ""
        if kind == "obj":
            filename = os.path.join(self.folder, self.prop(el, "filename", ""))
            if not os.path.isfile(filename):
                self.warn(el, f"mesh file {os.path.relpath(filename, self.folder)} is missing; shape skipped")
                return
        bsdfs = [c for c in el if c.tag == "bsdf" or (c.tag == "ref" and self.resolve(c).tag == "bsdf")]
        material = self.material(bsdfs[0]) if bsdfs else self.material(ET.Element("bsdf", type="diffuse"))
        radiance = None
        for c in el:
            e = self.resolve(c) if c.tag == "ref" else c
            if e.tag == "emitter":
                if e.get("type") != "area":
                    self.warn(e, "only area emitters can sit on a shape; ignored")
                    continue
                radiance = self.prop(e, "radiance", np.ones(3))
        if kind == "sphere":
            center = self.prop(el, "center", np.zeros(3))
            radius = self.prop(el, "radius", 1.0)
            local = np.eye(4)
            local[:3, :3] *= radius
            local[:3, 3] = center
            matrix = matrix @ local
        out.append(Shape(element_name(el), kind, matrix, material, filename=filename,
                         face_normals=bool(self.prop(el, "face_normals", False)), radiance=radiance,
                         name=el.get("id") or (os.path.splitext(os.path.basename(filename))[0] if filename else kind)))

    # --- emitters
    def emitter(self, el, scene: MitsubaScene) -> None:
        kind = el.get("type")
        matrix = self.prop(el, "to_world", None)
        if matrix is None:
            matrix = self.prop(el, "toWorld", np.eye(4))
        if kind == "point":
            pos = self.prop(el, "position", None)
            if pos is None:
                pos = matrix[:3, 3]
            scene.lights.append(PointLight(element_name(el), np.asarray(pos, np.float64),
                                           self.prop(el, "intensity", np.ones(3))))
        elif kind == "spot":
            cutoff = self.prop(el, "cutoff_angle", self.prop(el, "cutoffAngle", 20.0))
            beam = self.prop(el, "beam_width", self.prop(el, "beamWidth", cutoff * 0.75))
            self.warn(el, "spot falloff approximated by Blender's spot blend (smoothstep instead of Mitsuba's "
                          "linear ramp between beam_width and cutoff_angle)")
            scene.lights.append(SpotLight(element_name(el), matrix, self.prop(el, "intensity", np.ones(3)),
                                          float(cutoff), float(beam)))
        elif kind == "envmap":
            fn = os.path.join(self.folder, self.prop(el, "filename", ""))
            scene.environment = Environment("envmap", filename=fn, matrix=matrix,
                                            scale=float(self.prop(el, "scale", 1.0)), element=element_name(el))
        elif kind == "constant":
            scene.environment = Environment("constant", radiance=self.prop(el, "radiance", np.ones(3)))
        elif kind == "area":
            pass  # declared by id, used by a shape
        else:
            self.warn(el, "emitter type is not supported; skipped")

    # --- camera
    def camera(self, el) -> Camera | None:
        kind = el.get("type")
        if kind not in ("perspective", "thinlens"):
            self.warn(el, "only perspective sensors are supported; no camera")
            return None
        if kind == "thinlens":
            self.warn(el, "thin-lens depth of field is not supported; converted as a pinhole camera")
        matrix = self.prop(el, "to_world", None)
        if matrix is None:
            matrix = self.prop(el, "toWorld", np.eye(4))
        fov = self.prop(el, "fov", None)
        if fov is None:
            focal = self.prop(el, "focal_length", self.prop(el, "focalLength", "50mm"))
            fov = math.degrees(2 * math.atan(36.0 / (2 * float(str(focal).rstrip("m")))))
            axis = "x"
        else:
            axis = self.prop(el, "fov_axis", self.prop(el, "fovAxis", "x"))
        film = next((c for c in el if c.tag == "film"), None)
        w, h = 768, 576  # Mitsuba's hdrfilm default
        if film is not None:
            w = int(self.prop(film, "width", w))
            h = int(self.prop(film, "height", h))
        width = self.width
        height = max(1, round(width * h / w))
        return Camera(matrix, float(fov), axis, width, height, (w, h),
                      near=float(self.prop(el, "near_clip", self.prop(el, "nearClip", 1e-2))),
                      far=float(self.prop(el, "far_clip", self.prop(el, "farClip", 1e4))), element=element_name(el))

    def integrator_depth(self, el) -> int | None:
        depth = self.prop(el, "max_depth", self.prop(el, "maxDepth", None))
        if depth is None:
            for child in el:
                if child.tag == "integrator":
                    return self.integrator_depth(child)
            return None
        return int(depth)


def parse(path: str, width: int = DEFAULT_WIDTH, text: str | None = None) -> MitsubaScene:
    """Read a Mitsuba scene file (or ``text``, with ``path`` as the folder meshes are relative to)."""
    try:
        root = ET.fromstring(text) if text is not None else ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise MitsubaError(f"{path}: not a readable XML file ({err})") from None
    if root.tag != "scene":
        raise MitsubaError(f"{path}: the root element is <{root.tag}>, not <scene>")
    p = _Parser(path, width)
    p.substitute(root)
    for el in root.iter():
        if "id" in el.attrib and el.tag in ("bsdf", "texture", "emitter", "shape"):
            p.ids[el.get("id")] = el
    scene = MitsubaScene(path, None)
    for el in root:
        if el.tag == "include":
            p.warn(el, "includes are not followed; ignored")
        elif el.tag == "sensor" and scene.camera is None:
            scene.camera = p.camera(el)
        elif el.tag == "shape":
            p.shapes(el, np.eye(4), scene.shapes)
        elif el.tag == "emitter":
            p.emitter(el, scene)
        elif el.tag == "integrator":
            scene.max_bounces = None if (d := p.integrator_depth(el)) is None or d < 0 else max(1, d - 1)
    if scene.camera is None:
        p.warnings.append("scene: no perspective <sensor>; the converted scene has no camera")
    scene.warnings = p.warnings
    return scene
