"""Virtual lights and their summing: the ``virtual_lights`` arrays every method hands over, the one gather that sums
them at shading points with interleaved sampling and distance clamping (``summing``) and the geometry-aware filter
that removes the interleaving pattern (``bilateral``). May import ``core``, ``materials`` and ``lights``."""
