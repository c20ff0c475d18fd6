"""Frames of an animation that share work: the state a method carries from frame to frame (``state``, saved as
arrays and JSON by ``persisted``), what moved between two frames (``motion``), and Moreau et al.'s path verification
with the lights' distribution maps (``path_verification``, ``distribution_map``). May import every layer below
``methods``; the methods it drives are handed to it, never imported."""
