"""What a ray finds where it hits: the ``surface`` (position, shading frame, diffuse colour, metallic weight) with
its diffuse bounce, the metallic GGX lobe with F82-tint Fresnel (``microfacet``) and image textures sampled at the
hit (``textures``). May import ``core`` only."""
