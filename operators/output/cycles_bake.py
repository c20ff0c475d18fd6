"""Cycles' own bake of one object's lightmap, the rival and the judge of ours (``vpl_addon.lightmap``): what a user
gets today from ``bpy.ops.object.bake`` into an Image Texture node's image, with the reference's unbiased Cycles
settings (``reference.configure_cycles``) and the bounce limit our extraction reads.

Each of our bake passes maps to Cycles' bake type and pass filter (``CYCLES_BAKES``): Diffuse Indirect is type
DIFFUSE with INDIRECT alone, colour off, so Cycles divides the light by the diffuse colour as ours does.
"""
from __future__ import annotations

import numpy as np

from .reference import configure_cycles

CYCLES_BAKES = {  # our pass -> (Cycles' bake type, its pass filter)
    "Diffuse Indirect": ("DIFFUSE", {"INDIRECT"}),
    "Diffuse Direct": ("DIFFUSE", {"DIRECT"}),
    "Diffuse": ("DIFFUSE", {"DIRECT", "INDIRECT"}),
    "Diffuse Color": ("DIFFUSE", {"COLOR"}),
    "Combined": ("COMBINED", {"EMIT", "DIRECT", "INDIRECT", "COLOR", "DIFFUSE", "GLOSSY", "TRANSMISSION"}),
}


def cycles_lightmap(bpy, obj, size: int, samples: int, bake_pass: str = "Diffuse Indirect",
                    uv_map: str | None = None, margin: int = 16, seed: int | None = None) -> np.ndarray:
    """(size,size,3) float32 the lightmap of ``obj`` baked by Cycles at ``samples`` samples per texel into UV map
    ``uv_map`` (None: the active one) with Cycles' ``seed`` (None: the references'), rows top first (v = 1 at row
    0) as our maps. The image node it bakes through is added to each of the object's materials and removed again,
    with its image."""
    scene = bpy.context.scene
    configure_cycles(scene, samples)
    if seed is not None:
        scene.cycles.seed = seed
    bounces = min(scene.vpl_gi.max_bounces, scene.vpl_gi.diffuse_bounces) if hasattr(scene, "vpl_gi") else None
    if bounces is not None:
        scene.cycles.max_bounces = scene.cycles.diffuse_bounces = bounces
    image = bpy.data.images.new(f"cycles bake {obj.name}", size, size, alpha=True, float_buffer=True)
    added = []
    try:
        for slot in obj.material_slots:
            material = slot.material
            material.use_nodes = True
            node = material.node_tree.nodes.new("ShaderNodeTexImage")
            node.image = image
            material.node_tree.nodes.active = node
            added.append((material, node))
        bpy.ops.object.select_all(action="DESELECT")
        obj.select_set(True)
        bpy.context.view_layer.objects.active = obj
        kind, passes = CYCLES_BAKES[bake_pass]
        bpy.ops.object.bake(type=kind, pass_filter=passes, margin=margin, use_clear=True, target="IMAGE_TEXTURES",
                            uv_layer=uv_map or "")
        pixels = np.empty(size * size * 4, np.float32)
        image.pixels.foreach_get(pixels)
        return np.ascontiguousarray(pixels.reshape(size, size, 4)[::-1, :, :3])
    finally:
        for material, node in added:
            material.node_tree.nodes.remove(node)
        bpy.data.images.remove(image)
