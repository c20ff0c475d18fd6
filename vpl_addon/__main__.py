"""``python -m vpl_addon``: the command line.

The engine imports no bpy; the commands live with the Blender side in ``operators/cli/commands.py``. This bootstrap
loads the extension's root folder as the package ``vpl_gi`` (the way Blender loads it as ``bl_ext.<repo>.vpl_gi``), so
that the relative imports between ``operators/`` and ``vpl_addon/`` work the same from a checkout.
"""
from __future__ import annotations

import importlib
import importlib.util
import pathlib
import sys

PACKAGE = "vpl_gi"


def extension_package():
    """The extension root as an importable package named ``vpl_gi`` (loaded once)."""
    if PACKAGE not in sys.modules:
        root = pathlib.Path(__file__).resolve().parent.parent
        spec = importlib.util.spec_from_file_location(PACKAGE, root / "__init__.py",
                                                      submodule_search_locations=[str(root)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = module
        spec.loader.exec_module(module)
    return sys.modules[PACKAGE]


def call(name: str, *args):
    """``<name>(*args)``, a function of the extension (``operators.cli.farm.render_chunk``), in this process after
    loading the extension: the entry a Dask worker runs. A task names this function, which any Python that has the
    extension on its path can import; the extension's own modules load only once it runs."""
    module, _, function = name.rpartition(".")
    extension_package()
    return getattr(importlib.import_module(f"{PACKAGE}.{module}"), function)(*args)


def main(argv=None) -> int:
    extension_package()
    return importlib.import_module(f"{PACKAGE}.operators.cli.commands").main(argv)


if __name__ == "__main__":
    sys.exit(main())
