"""Paths through the scene that more than one method uses: light paths leaving VPLs where they bounce
(``light_paths``), the camera's first hits (``gbuffer``) and points it sees (``camera_points``), camera paths
continued over metal to the gather (``over_metal``, on ``vertices``). May import ``core``, ``materials``,
``lights`` and ``gather``."""
