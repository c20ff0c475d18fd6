"""The RenderEngine: F12, the viewport's Rendered shading, and the sequence state a frame renders with."""
