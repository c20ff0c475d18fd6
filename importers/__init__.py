"""Public test scenes made Blender scenes: Mitsuba XML (``mitsuba``), Wavefront OBJ meshes (``wavefront``) and the
Cornell box's measured data (``cornell_measured``) read into plain data without bpy, and ``shared_scenes`` (the one
module here that imports bpy) building a .blend from that data for the named scenes of ``../shared/scenes``. Imports
nothing else of the repository; the command line (``import-scenes``) and the bench use it."""
