"""Reading the Blender scene into the engine's arrays: objects, materials' shader nodes, the world."""
