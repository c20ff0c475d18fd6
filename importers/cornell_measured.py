"""The Cornell box from its measured data (``cornell_box_data.json``: quads in millimetres, camera, the light's
emission spectrum and the walls' reflectance spectra) -> the same plain data as a Mitsuba scene, no bpy.

Spectra become linear sRGB by integrating against the CIE 1931 matching functions (``mitsuba.spectrum_to_rgb``),
normalised so that a flat spectrum keeps its value; millimetres become metres. The light quad is flush with the
ceiling in the data; it is lowered by 0.5 mm, as Mitsuba's cbox does.
"""
from __future__ import annotations

import json
import math
import os

import numpy as np

from .mitsuba import Camera, Material, MitsubaScene, Shape, look_at, spectrum_to_rgb

MM = 1e-3
LIGHT_DROP_MM = 0.5
WALL_MATERIAL = {"floor": "white", "ceiling": "white", "back_wall": "white", "right_wall_green": "green",
                 "left_wall_red": "red", "short_block": "white", "tall_block": "white"}
DATA = "cornell_box_data.json"


def parse(folder: str, width: int = 256) -> MitsubaScene:
    path = os.path.join(folder, DATA)
    with open(path) as f:
        data = json.load(f)
    wl = data["reflectance_wavelength_nm"]
    materials = {key: Material(key.capitalize(), tuple(float(c) for c in np.clip(spectrum_to_rgb(wl, values), 0, 1)))
                 for key, values in data["reflectance"].items()}
    scene = MitsubaScene(path, None)
    scale = np.diag([MM, MM, MM, 1.0])
    for name, quads in data["geometry_quads"].items():
        quads = np.asarray(quads, np.float64)
        if quads.ndim == 2:
            quads = quads[None]
        verts = quads.reshape(-1, 3)
        faces = [list(range(4 * i, 4 * i + 4)) for i in range(len(quads))]
        if name == "light":
            spec = data["light_emission_spectrum"]
            radiance = spectrum_to_rgb(spec["wavelength_nm"], spec["value"])
            verts = verts - [0.0, LIGHT_DROP_MM, 0.0]
            scene.shapes.append(Shape(f'{DATA} "light"', "polygons", scale, Material("Light", (0.0, 0.0, 0.0)),
                                      radiance=radiance, name="Light", polygons=(verts, faces)))
            continue
        scene.shapes.append(Shape(f'{DATA} "{name}"', "polygons", scale, materials[WALL_MATERIAL[name]],
                                  name=name, polygons=(verts, faces)))
    cam = data["camera"]
    origin = np.asarray(cam["position"], np.float64) * MM
    matrix = look_at(origin, origin + np.asarray(cam["direction"], np.float64), cam["up"])
    fov = math.degrees(2 * math.atan(cam["film_width_m"] / (2 * cam["focal_length_m"])))
    aspect = cam["film_height_m"] / cam["film_width_m"]
    scene.camera = Camera(matrix, fov, "x", width, max(1, round(width * aspect)), (width, round(width * aspect)))
    scene.max_bounces = 8
    return scene
