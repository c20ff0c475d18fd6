"""The packages the engine cannot render without, checked before anything imports them.

The extension bundles them as wheels (``blender_manifest.toml``); one may still fail to load: a Blender whose Python
or numpy the bundled wheel does not support (numba 0.62.1, the last for Intel Macs, refuses numpy 2.5 of Blender
5.1 and newer), a zip of another platform, a wheel Blender could not unpack. ``problem()`` names the first such
package with its own error and the fix, in one line, so that registration can say it instead of failing.
"""
from __future__ import annotations

import importlib

# import name -> what the engine needs it for
REQUIRED = {
    "numpy": "arrays",
    "numba": "compiled kernels",
    "llvmlite": "numba's compiler",
    "embreex": "ray tracing",
    "scipy": "k-d trees",
}
FIX = ("install the VPL GI zip of this platform (Edit > Preferences > Get Extensions > Install from Disk); on an "
       "Intel Mac use Blender 5.0 or older (numba's last Intel Mac wheel needs numpy 2.3 or older)")


def problem() -> str | None:
    """One line naming the first required package that does not load, why, and the fix; None when all load."""
    for name, purpose in REQUIRED.items():
        try:
            importlib.import_module(name)
        except Exception as exc:  # ImportError, and numba's own check of numpy's version
            reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            return f"VPL GI cannot render: {name} ({purpose}) does not load: {reason}. Fix: {FIX}"
    return None
