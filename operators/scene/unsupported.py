"""Blender features VPL GI does not render, met while extracting a scene. Each is left out or approximated, and
``Unsupported`` turns what it met into one warning per case naming every object, material or setting involved, however
many objects (or instances of one) show it.

Left out: light portals (they only guide Cycles' sampling of the world, so they are no light here either), the faces
of a material with only a Volume shader (a fog box is not a solid box), Volume objects, hair (Curves objects and hair
particle systems drawn as paths) and point clouds. Approximated: a Volume shader beside a Surface (the surface alone),
the world's Volume (none), light and shadow linking (every light reaches everything), shadow catchers and holdouts
(ordinary objects, as Cycles renders a holdout to every ray but the camera's; a Holdout shader black), motion blur (the
frame's instant), Cycles' ray visibility and Indirect Only (seen by every ray).
"""
from __future__ import annotations

from .shader_nodes import MaterialTable, output_shader

# case -> (feature, what VPL GI does); a warning is "feature: what it does: the names met"
CASES = {
    "portal": ("portal", "light portals only guide Cycles' sampling of the world; they give no light"),
    "volume only": ("volume", "VPL GI renders no volumes; the faces of a material with only a Volume shader are left "
                              "out"),
    "volume and surface": ("volume", "VPL GI renders no volumes; these materials render their Surface without their "
                                     "Volume shader"),
    "world volume": ("volume", "VPL GI renders no volumes; the world's Volume shader is ignored"),
    "volume object": ("volume", "VPL GI renders no volumes; Volume objects are left out"),
    "hair": ("hair", "VPL GI renders no hair; it is left out (an emitter's mesh renders)"),
    "point cloud": ("point cloud", "VPL GI renders no point clouds; they are left out"),
    "light linking": ("light linking", "light and shadow linking are ignored; every light reaches everything"),
    "shadow catcher": ("shadow catcher", "shadow catchers render as ordinary objects"),
    "holdout": ("holdout", "holdouts render as ordinary objects, not as holes in the image (Cycles renders them so "
                           "to every ray but the camera's)"),
    "holdout shader": ("holdout", "the Holdout shader renders black and opaque, not as a hole in the image"),
    "motion blur": ("motion blur", "the frame renders at its instant, without motion blur"),
    "ray visibility": ("ray visibility", "Cycles' ray visibility and Indirect Only are ignored; these are seen by "
                                         "every ray"),
}
LEFT_OUT_TYPES = {"CURVES": "hair", "POINTCLOUD": "point cloud", "VOLUME": "volume object"}
RAYS = ("camera", "diffuse", "glossy", "transmission", "volume_scatter", "shadow")  # Object.visible_<ray>


def _portal(obj) -> bool:
    """Whether ``obj`` is an area light that Cycles uses as a light portal."""
    return obj.type == "LIGHT" and obj.data.type == "AREA" and getattr(getattr(obj.data, "cycles", None),
                                                                       "is_portal", False)


def _emissive(obj, materials: MaterialTable) -> bool:
    """Whether a material of geometry ``obj`` glows (a constant or mapped emission)."""
    rows = [materials.rows[materials.id_of(s.material) - 1] for s in obj.material_slots if s.material is not None]
    return any(any(row.get("emission", ())) or "emission" in row.get("maps", {}) for row in rows)


def _hair_systems(obj) -> list[str]:
    """Names of the hair particle systems of ``obj`` that Cycles renders as strands (enabled for render, drawn as
    Path; hair drawn as objects or collections arrives as instances)."""
    return [m.particle_system.name for m in obj.modifiers if m.type == "PARTICLE_SYSTEM" and m.show_render
            and m.particle_system.settings.type == "HAIR" and m.particle_system.settings.render_type == "PATH"]


class Unsupported:
    """The unsupported features met in one extraction, by case (``CASES``), and their warnings."""

    def __init__(self):
        self.met: dict[str, dict[str, None]] = {}  # case -> names, in the order met
        self._checked: set[str] = set()  # objects whose settings have been looked at
        self._volume: dict[str, str | None] = {}  # material -> "volume only", "volume and surface" or None

    def note(self, case: str, name: str):
        self.met.setdefault(case, {})[name] = None

    def warnings(self, materials: MaterialTable) -> list[str]:
        """One warning per case met, in ``CASES`` order."""
        for name in materials.holdouts:
            self.note("holdout shader", f"material {name!r}")
        return [f"{CASES[case][0]}: {CASES[case][1]}: {', '.join(self.met[case])}" for case in CASES
                if case in self.met]

    def scene(self, depsgraph):
        """Motion blur, the world's volume, and holdout or Indirect Only collections of the view layer."""
        scene = depsgraph.scene
        if scene.render.use_motion_blur:
            self.note("motion blur", f"scene {scene.name!r} (Render > Motion Blur)")
        world = depsgraph.scene_eval.world
        if world is not None and output_shader(world, "Volume") is not None:
            self.note("world volume", f"world {world.name!r}")
        self._collections(depsgraph.view_layer.layer_collection, depsgraph.view_layer.name)

    def _collections(self, layer, view_layer: str):
        """Holdout and Indirect Only collections under ``layer`` that hold objects (excluded ones do not render)."""
        for child in layer.children:
            if child.exclude or not child.collection.all_objects:
                continue
            if child.holdout:
                self.note("holdout", f"collection {child.name!r} (Holdout in view layer {view_layer!r})")
            if child.indirect_only:
                self.note("ray visibility", f"collection {child.name!r} (Indirect Only in view layer {view_layer!r})")
            self._collections(child, view_layer)

    def left_out(self, obj) -> bool:
        """Whether ``obj`` is not rendered at all (a light portal, hair curves, a point cloud, a Volume object);
        noted when so."""
        if _portal(obj):
            self.note("portal", f"area light {obj.name!r}")
            return True
        case = LEFT_OUT_TYPES.get(obj.type)
        if case is not None:
            self.note(case, f"object {obj.name!r}")
        return case is not None

    def volume_faces(self, obj, materials: MaterialTable) -> list[int]:
        """The material ids of geometry ``obj`` whose faces are left out (only a Volume shader); a Volume shader
        beside a Surface is noted and the surface renders."""
        left_out = []
        for slot in obj.material_slots:
            material = slot.material
            if material is None:
                continue
            if material.name_full not in self._volume:
                self._volume[material.name_full] = None if output_shader(material, "Volume") is None else \
                    "volume and surface" if output_shader(material) is not None else "volume only"
            case = self._volume[material.name_full]
            if case == "volume only":
                self.note(case, f"material {material.name!r} on object {obj.name!r}")
                left_out.append(materials.id_of(material))
            elif case is not None:
                self.note(case, f"material {material.name!r}")
        return left_out

    def instance(self, inst, materials: MaterialTable):
        """The settings VPL GI ignores on an instance's object and on the object instancing it (Cycles combines
        both); each object is looked at once. After its geometry is read: light linking matters on emitters only."""
        self._settings(inst.object, materials)
        if inst.is_instance:
            self._settings(inst.parent, materials)

    def _settings(self, obj, materials: MaterialTable):
        """Light linking of ``obj``, and for geometry (or the object instancing it) shadow catcher, holdout, ray
        visibility and hair particles (a lamp's flags of the same names are not these features: Blender sets a new
        lamp's shadow catcher flag and unsets its camera visibility)."""
        if obj.name in self._checked:
            return
        self._checked.add(obj.name)
        name = f"{'light' if obj.type == 'LIGHT' else 'object'} {obj.name!r}"
        links = obj.light_linking
        linked = [f"{role} {c.name!r}" for role, c in (("receivers", links.receiver_collection),
                                                       ("blockers", links.blocker_collection)) if c is not None]
        if linked and (obj.type == "LIGHT" or _emissive(obj, materials)):
            self.note("light linking", f"{name} ({', '.join(linked)})")
        if obj.type == "LIGHT":
            return
        if obj.is_shadow_catcher:
            self.note("shadow catcher", name)
        if obj.is_holdout:
            self.note("holdout", name)
        hidden = [ray for ray in RAYS if not getattr(obj, f"visible_{ray}")]
        if hidden:
            self.note("ray visibility", f"{name} ({', '.join(hidden)} off)")
        for system in _hair_systems(obj):
            self.note("hair", f"particle system {system!r} on object {obj.name!r}")
