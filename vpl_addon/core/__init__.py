"""The engine's ground floor: the scene as arrays (``scene``), the pinhole camera, the one ray tracer (embreex),
random numbers and sample patterns (``sampling``), luminance (``color``), the pass names and their order
(``passes``), EXR files (``exr``) and handing freed memory back (``memory``). Imports nothing of the engine above
it (``scene`` names ``lights.Light`` in an annotation only)."""
