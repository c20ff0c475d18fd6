"""The engine: global illumination with virtual lights, in numpy, scipy and embreex; no bpy anywhere below here.

Subpackages by kind, each importing only its own or a lower layer (checked by ``tests/repository/test_layout.py``):

    core        scene arrays, camera, tracer, sampling, colour, passes, EXR, memory     imports nothing of the engine
    materials   the surface a ray hits, its microfacet lobe, textures                   core
    lights      light sources, their sampling, direct light                             core, materials
    gather      virtual lights, the summing gather, the geometry-aware filter           ... lights
    paths       light paths, camera path vertices, the G-buffer, paths over metal      ... gather
    sequence    state kept between frames, motion, path verification                   ... paths
    methods     one subpackage per paper, with the modules only it uses                ... sequence
    render.py   one frame: extraction's ``Scene`` in, passes out                         everything above
    lightmap    lightmaps of objects' UV maps from one VPL set (Cycles' bake types)     render and all above
    progressive.py  the viewport's progressive render on a background thread             render and all above
    precompile.py   the kernels compiled before the first render, on a background thread  render and all above
    evaluation  metrics, comparison with Cycles, temporal error, convergence            core (and itself)

Blender's side (``operators/``) builds a ``core.scene.Scene`` and calls ``render.render`` (or, for the 3D view,
``progressive.ProgressiveRenderer``); nothing here calls back.
"""
