"""Rooms of UV-mapped quads, one object per face, built without Blender for the lightmap tests."""
import numpy as np

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene

UNIT = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


def quad(corners, island=(0.0, 1.0)):
    """Two triangles of the quad ``corners`` (counter-clockwise from the front) and their UVs, the square
    ``island`` = (low, high) of the map."""
    lo, hi = island
    uv = lo + (hi - lo) * UNIT
    c = np.asarray(corners, float)
    return np.stack([c[[0, 1, 2]], c[[0, 2, 3]]]), np.stack([uv[[0, 1, 2]], uv[[0, 2, 3]]])


def box_faces(lo, hi, inward=True):
    """The six faces of the box [lo, hi]^3 as quads facing into it (or out of it)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = {
        "floor": [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)],
        "ceiling": [(x0, y0, z1), (x0, y1, z1), (x1, y1, z1), (x1, y0, z1)],
        "left": [(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)],
        "right": [(x1, y0, z0), (x1, y0, z1), (x1, y1, z1), (x1, y1, z0)],
        "back": [(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)],
        "front": [(x0, y0, z0), (x0, y0, z1), (x1, y0, z1), (x1, y0, z0)],
    }
    return {name: c if inward else c[::-1] for name, c in faces.items()}


def scene_of(objects: dict, lights, albedo=0.5, island=(0.0, 1.0), camera=None) -> Scene:
    """A scene of the quads ``objects`` (name -> corners), one object each, of one grey material; ``camera`` (None:
    an orthographic one at the origin looking down)."""
    tris, uvs, ids = [], [], []
    for number, corners in enumerate(objects.values()):
        t, uv = quad(corners, island)
        tris.append(t)
        uvs.append(uv)
        ids += [number, number]
    materials = Materials.make([{"name": "grey", "base_color": (albedo,) * 3}])
    cam = camera or Camera(np.eye(4), 8, 8, view_window(8, 8, orthographic=True, ortho_scale=1.0), orthographic=True)
    return Scene.build(np.concatenate(tris), materials, list(lights), cam, uvs=np.concatenate(uvs),
                       material=np.ones(len(ids)), object_id=ids, object_names=list(objects))
