"""The repository's layout, checked on the source (AST, nothing imported): the engine's layers import one way, the
engine and the scene parsers import no Blender, the extension never imports the bench, no modules import each other
in a circle, folders stay small, and a module only one method uses lives with that method.

Imports are read wherever they are (a function's lazy import counts) except under ``if TYPE_CHECKING:``, which
never runs (``core.scene`` names ``lights.Light`` in an annotation that way).
"""
from __future__ import annotations

import ast
from collections import defaultdict

from conftest import ROOT

# The engine's layers, lowest first: each may import its own and the lower ones (see vpl_addon/__init__.py).
LAYERS = ("core", "materials", "lights", "gather", "paths", "sequence", "methods", "render", "lightmap",
          "progressive", "precompile")
ALLOWED = {layer: set(LAYERS[:i + 1]) for i, layer in enumerate(LAYERS)}
ALLOWED["evaluation"] = {"core", "evaluation"}  # judges outputs; nothing of the engine imports it
ALLOWED["__main__"] = set()  # the bootstrap reaches operators.cli.commands by name, not by import
NO_BLENDER = {"bpy", "mathutils", "bl_math", "gpu", "bmesh"}
# The scene parsers: plain data, unit-tested without Blender (their builder, importers/shared_scenes.py, uses bpy).
PARSERS = ("importers/mitsuba.py", "importers/wavefront.py", "importers/cornell_measured.py")
MAX_MODULES_PER_FOLDER = 12
FOLDERS = ("vpl_addon", "operators", "importers", "bench")  # the repository's Python, the tests aside


def _module_name(path, root) -> tuple[str, ...]:
    parts = path.relative_to(root).with_suffix("").parts
    return parts[:-1] if parts[-1] == "__init__" else parts


def _is_package(path) -> bool:
    return path.name == "__init__.py"


def _exists(parts, root) -> bool:
    base = root.joinpath(*parts)
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def _skip_type_checking(tree):
    """The tree's nodes, without the bodies of ``if TYPE_CHECKING:`` blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and isinstance(child.test, ast.Name) and child.test.id == "TYPE_CHECKING":
                stack.extend(child.orelse)
                continue
            stack.append(child)


def imports(path, root=ROOT) -> list[tuple[str, ...] | str]:
    """What ``path`` imports: repository modules as tuples of parts from the root (relative imports resolved; a
    ``from . import x`` names module x when there is one), everything else as its top-level name."""
    own = _module_name(path, root)
    package = own if _is_package(path) else own[:-1]
    found = []
    for node in _skip_type_checking(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [alias.name.split(".")[0] for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                found.append(node.module.split(".")[0])
                continue
            base = package[:len(package) - (node.level - 1)] + tuple(node.module.split(".") if node.module else ())
            subs = [base + (alias.name,) for alias in node.names if _exists(base + (alias.name,), root)]
            found += subs or [base or ("<extension>",)]
    return found


def sources(folder: str, root=ROOT):
    return sorted(p for p in (root / folder).rglob("*.py") if "__pycache__" not in p.parts)


def _layer(parts: tuple[str, ...]) -> str:
    """``vpl_addon.<layer>...`` -> layer (``render`` and the package itself are the top)."""
    if len(parts) < 2 or parts[1] == "__init__":
        return "render"
    return parts[1]


def engine_violations(root=ROOT) -> list[str]:
    bad = []
    for path in sources("vpl_addon", root):
        own = _module_name(path, root)
        layer = _layer(own)
        for target in imports(path, root):
            where = f"{path.relative_to(root)} imports {'.'.join(target) if isinstance(target, tuple) else target}"
            if isinstance(target, str):
                if target in NO_BLENDER:
                    bad.append(f"{where}: the engine runs without Blender")
                continue
            if target[0] != "vpl_addon":
                bad.append(f"{where}: the engine imports nothing outside vpl_addon/")
                continue
            if len(target) == 1:
                continue  # the package's own docstring module
            to = _layer(target)
            if to not in ALLOWED[layer]:
                bad.append(f"{where}: layer {layer!r} may import only {sorted(ALLOWED[layer])}")
            elif layer == to == "methods" and len(own) > 2 and len(target) > 2 and own[2] != target[2] and \
                    (root / "vpl_addon" / "methods" / target[2] / "__init__.py").is_file():
                bad.append(f"{where}: a method imports no other method")  # the contract (methods.base) is no method
    return bad


def test_the_engine_layers_import_one_way_and_never_blender():
    assert engine_violations() == []


def test_the_check_catches_an_upward_import(tmp_path):
    """The check above, run on a copy of the engine's core with one upward import added, reports that import."""
    import shutil
    copy = tmp_path / "repo"
    shutil.copytree(ROOT / "vpl_addon", copy / "vpl_addon", ignore=shutil.ignore_patterns("__pycache__"))
    sampling = copy / "vpl_addon" / "core" / "sampling.py"
    sampling.write_text(sampling.read_text() + "\n\ndef _late():\n    from ..methods import METHODS\n"
                        "    from ..lights.direct import direct_light\n    import bpy\n")
    assert sorted(engine_violations(copy)) == [
        "vpl_addon/core/sampling.py imports bpy: the engine runs without Blender",
        "vpl_addon/core/sampling.py imports vpl_addon.lights.direct: layer 'core' may import only ['core']",
        "vpl_addon/core/sampling.py imports vpl_addon.methods: layer 'core' may import only ['core']"]


def test_the_parsers_and_the_engine_need_no_blender_and_the_extension_no_bench():
    bad = []
    for path in [ROOT / p for p in PARSERS]:
        bad += [f"{path.name} imports {t}" for t in imports(path) if t in NO_BLENDER or isinstance(t, tuple)
                and t[0] != "importers"]
    for folder in ("operators", "importers", "vpl_addon"):
        for path in sources(folder):
            for t in imports(path):
                rel = (str(path.relative_to(ROOT)), ".".join(t) if isinstance(t, tuple) else t)
                if isinstance(t, tuple) and t[0] == "bench":
                    bad.append(f"{rel[0]} imports {rel[1]}: bench/ is not shipped in the extension")
                if folder == "importers" and isinstance(t, tuple) and t[0] == "operators":
                    bad.append(f"{rel[0]} imports {rel[1]}: importers are below the Blender side")
    assert bad == []


def import_graph(root=ROOT) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
    """Module -> the repository modules it imports, at the top or inside a function (the extension's root package
    ``__init__.py`` is ``("<extension>",)``, as ``imports`` names it)."""
    graph = {_module_name(path, root): {t for t in imports(path, root) if isinstance(t, tuple)}
             for folder in FOLDERS for path in sources(folder, root)}
    graph[("<extension>",)] = {t for t in imports(root / "__init__.py", root) if isinstance(t, tuple)}
    return graph


def circles(graph) -> list[list[str]]:
    """The groups of modules that import each other, directly or round a loop (strongly connected components of
    more than one module, or one that imports itself), each sorted, by Tarjan's algorithm."""
    order, low, stack, found = {}, {}, [], []

    def visit(module):
        order[module] = low[module] = len(order)
        stack.append(module)
        for target in graph.get(module, ()):
            if target not in graph:
                continue
            if target not in order:
                visit(target)
                low[module] = min(low[module], low[target])
            elif target in stack:
                low[module] = min(low[module], order[target])
        if low[module] == order[module]:
            group = stack[stack.index(module):]
            del stack[stack.index(module):]
            if len(group) > 1 or module in graph[module]:
                found.append(sorted(".".join(m) for m in group))

    for module in sorted(graph):
        if module not in order:
            visit(module)
    return sorted(found)


def test_no_modules_import_each_other_in_a_circle():
    assert circles(import_graph()) == []


def test_the_check_catches_a_circle_through_a_function_level_import(tmp_path):
    """The check above, run on a copy of the repository where the farm imports the command line's module inside a
    function, reports the two modules."""
    import shutil
    copy = tmp_path / "repo"
    for folder in FOLDERS:
        shutil.copytree(ROOT / folder, copy / folder, ignore=shutil.ignore_patterns("__pycache__", "results"))
    shutil.copy(ROOT / "__init__.py", copy / "__init__.py")
    farm = copy / "operators" / "cli" / "farm.py"
    farm.write_text(farm.read_text() + "\n\ndef _late():\n    from .commands import main\n")
    assert circles(import_graph(copy)) == [["operators.cli.commands", "operators.cli.farm"]]


def test_folders_stay_small():
    counts = {folder.relative_to(ROOT): len([p for p in folder.glob("*.py") if p.name != "__init__.py"])
              for folder in [ROOT / "vpl_addon", *(ROOT / "vpl_addon").rglob("*/")] if folder.is_dir()
              and folder.name != "__pycache__"}
    assert max(counts.values()) <= MAX_MODULES_PER_FOLDER, counts


def test_a_module_only_one_method_uses_lives_with_that_method():
    """Outside ``methods/``, every engine module is used by the engine's own frame pipeline, by the Blender side,
    by two methods or by none of them (a shared building block): never by exactly one method and nothing else."""
    users = defaultdict(set)
    for folder in ("vpl_addon", "operators", "importers"):
        for path in sources(folder):
            own = _module_name(path, ROOT)
            user = own[2] if own[:2] == ("vpl_addon", "methods") and len(own) > 2 else ".".join(own)
            for t in imports(path):
                if isinstance(t, tuple) and t[0] == "vpl_addon" and t[1:2] != ("methods",):
                    users[t].add(user)
    methods = {p.name for p in (ROOT / "vpl_addon" / "methods").iterdir() if (p / "__init__.py").is_file()}
    lonely = {}
    for module, who in users.items():
        others = who - {".".join(module)}
        if len(others) == 1 and others <= methods:
            lonely[".".join(module)] = others.pop()
    assert lonely == {}, "move these into their method's folder"
