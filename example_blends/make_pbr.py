"""Build example_blends/cornell_pbr.blend: the area-lit Cornell box whose floor and tall block wear a textured PBR
material as Blender's glTF importer builds it.

The material test of issue 21: a Principled BSDF whose Base Color (sRGB image x a colour factor), Roughness and
Metallic (one Non-Color image through Separate Color, G and B, x factors) and Normal (a tangent-space normal map)
come from image textures. The floor and the block are made here with UVs, exported to glTF with those images and
imported back with Blender's own importer (shipped with ``bpy``), so the node pattern is the importer's, not ours.
The dielectric specular layer is on (Specular IOR Level 0.5, IOR 1.5, as glTF asks). Images: 64x64, generated.
Run from the repository root (it reuses make_examples.py's Cornell box):

    .venv-blender/4.2/bin/python example_blends/make_pbr.py [--out DIR] [--force]
"""
import math
import os
import tempfile

import bpy
import numpy as np

from make_examples import add_area_light, add_short_box, cornell_base
from scene_building import box_geometry, main, mesh_object

SIZE = 64


def _image(name, pixels, non_color):
    image = bpy.data.images.new(name, SIZE, SIZE, alpha=False)
    if non_color:  # before the pixels: changing it regenerates a generated image's buffer
        image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(np.concatenate([pixels, np.ones((SIZE, SIZE, 1))], axis=2).astype(np.float32).ravel())
    image.update()
    return image


def make_images():
    """(base colour, metallic-roughness, normal map) as Blender images, row 0 at the bottom."""
    y, x = (np.mgrid[0:SIZE, 0:SIZE] + 0.5) / SIZE
    cells = ((x * 4).astype(int) + (y * 4).astype(int)) % 2
    base = np.where(cells[..., None], [0.85, 0.55, 0.3], [0.3, 0.6, 0.8])  # two colours, in sRGB
    roughness = 0.25 + 0.6 * x  # a ramp across u
    metallic = ((y * 4).astype(int) == 3).astype(float)  # one band of metal
    mr = np.stack([np.zeros_like(x), roughness, metallic], axis=2)
    slope = 0.6 * np.cos(2 * math.pi * 3 * x)  # ridges along v: the normal tilts along u
    n = np.stack([-slope, np.zeros_like(x), np.ones_like(x)], axis=2)
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return _image("BaseColor", base, False), _image("MetalRough", mr, True), _image("Normal", 0.5 * n + 0.5, True)


def pbr_material(images):
    """Principled BSDF fed by the three images the way glTF's metallic-roughness material reads them."""
    base, mr, normal = images
    mat = bpy.data.materials.new("PBR")
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["IOR"].default_value = 1.5
    tex = [nodes.new("ShaderNodeTexImage") for _ in range(3)]
    for node, image in zip(tex, images):
        node.image = image
    links.new(tex[0].outputs["Color"], bsdf.inputs["Base Color"])
    sep = nodes.new("ShaderNodeSeparateColor")
    links.new(tex[1].outputs["Color"], sep.inputs[0])
    links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    nmap = nodes.new("ShaderNodeNormalMap")
    links.new(tex[2].outputs["Color"], nmap.inputs["Color"])
    links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def box_uvs(verts, faces, scale=0.5):
    """Per-loop UVs (one list per face) of a box mapping: each face projected on its dominant plane, ``scale`` metres
    a tile."""
    out = []
    for f in faces:
        p = np.array([verts[i] for i in f], float)
        n = np.abs(np.cross(p[1] - p[0], p[2] - p[0]))
        axes = [a for a in range(3) if a != int(np.argmax(n))]
        out.append([tuple(p[k, axes] / scale) for k in range(len(f))])
    return out


def textured_objects(material):
    """The floor and the tall block, with UVs and the PBR material."""
    floor_v = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    floor_f = [(0, 1, 2, 3)]
    block_v, block_f = box_geometry(0.6, 0.6, 1.2)
    made = []
    for name, verts, faces, loc, angle in (("Floor", floor_v, floor_f, (0, 0, 0), 0.0),
                                           ("TallBox", block_v, block_f, (-0.35, 0.3, 0.0), 17.0)):
        obj = mesh_object(name, verts, faces, material, location=loc, rotation=(0.0, 0.0, math.radians(angle)))
        layer = obj.data.uv_layers.new(name="UVMap")
        uvs = box_uvs(verts, faces, 2.0 if name == "Floor" else 0.6)
        for poly, face_uv in zip(obj.data.polygons, uvs):
            for loop, uv in zip(poly.loop_indices, face_uv):
                layer.data[loop].uv = uv
        made.append(obj)
    return made


def through_gltf(objects, images):
    """Export ``objects`` to a .glb and import them back with Blender's importer (replacing them); the images are
    written as PNG files first, which the exporter copies as they are."""
    with tempfile.TemporaryDirectory() as tmp:
        for image in images:
            image.filepath_raw = os.path.join(tmp, image.name + ".png")
            image.file_format = "PNG"
            image.save()
        path = os.path.join(tmp, "pbr.glb")
        bpy.ops.object.select_all(action="DESELECT")
        for obj in objects:
            obj.select_set(True)
        bpy.ops.export_scene.gltf(filepath=path, use_selection=True, export_format="GLB", export_yup=True,
                                  export_cameras=False, export_lights=False)
        for obj in objects:
            bpy.data.objects.remove(obj)
        bpy.ops.import_scene.gltf(filepath=path)
        for image in bpy.data.images:
            if image.name not in {i.name for i in images} and not image.packed_file:
                image.pack()


def build_cornell_pbr():
    mats = cornell_base()
    add_short_box(mats)
    add_area_light("SQUARE")
    for name in ("Floor", "TallBox"):
        bpy.data.objects.remove(bpy.data.objects[name])
    images = make_images()
    through_gltf(textured_objects(pbr_material(images)), images)
    for mat in list(bpy.data.materials):  # the original, replaced by what the importer made of it
        if mat.users == 0:
            bpy.data.materials.remove(mat)
    for image in images:
        bpy.data.images.remove(image)


SCENES = {"cornell_pbr": build_cornell_pbr}


if __name__ == "__main__":
    main(SCENES, __doc__)
