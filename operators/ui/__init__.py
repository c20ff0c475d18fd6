"""The render properties' settings and panels: what the user sees and sets."""
