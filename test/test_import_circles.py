"""No import circle between the packages of epuck_ros: each layer imports only the ones below it
(docs/ARCHITECTURE.md, "Who imports whom"), counting the imports inside functions too."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'epuck_ros'


def package_imports() -> dict[str, set[str]]:
    """For each top-level part of epuck_ros (a sub-package or module), the other parts it imports anywhere."""
    edges: dict[str, set[str]] = {}
    for path in PACKAGE.rglob('*.py'):
        part = path.relative_to(PACKAGE).parts[0].removesuffix('.py')
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            else:
                continue
            for name in names:
                parts = name.split('.')
                if parts[0] == 'epuck_ros' and len(parts) > 1 and parts[1] != part:
                    edges.setdefault(part, set()).add(parts[1])
    return edges


def reachable(edges: dict[str, set[str]], start: str) -> set[str]:
    seen: set[str] = set()
    stack = [start]
    while stack:
        for nxt in edges.get(stack.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                stack.append(nxt)
    return seen


def test_experiments_and_webots_are_in_no_import_circle():
    """`webots_controller --headless` is the experiments' command: it lives above both (epuck_ros.webots_controller),
    so webots, which the experiments' script trials use, never imports the experiments."""
    edges = package_imports()
    assert 'webots' in edges['experiments']   # a script trial's seats
    for part in ('experiments', 'webots', 'evolution'):
        assert part not in reachable(edges, part), f'{part} imports something that imports {part}'


def test_no_part_of_the_package_is_in_an_import_circle():
    """The `bag` command played bags through `nodes.play_node` while the nodes record with `bag`: the command now
    lives above both (`epuck_ros.bag_cli`), as `webots_controller` does, and no part reaches itself."""
    edges = package_imports()
    assert 'nodes' in edges['bag_cli'] and 'bag' in edges['nodes']
    assert [part for part in sorted(edges) if part in reachable(edges, part)] == []


def module_name(path: Path) -> str:
    """`epuck_ros/world/data.py` -> `epuck_ros.world.data`; a package's `__init__.py` -> the package."""
    parts = path.relative_to(PACKAGE.parent).with_suffix('').parts
    return '.'.join(parts[:-1] if parts[-1] == '__init__' else parts)


def module_imports() -> dict[str, set[str]]:
    """For each module of epuck_ros, the package's modules it imports anywhere in it: at module level, under
    `if TYPE_CHECKING:` and inside functions (`from epuck_ros.world import data` imports the module `data`;
    `from epuck_ros.world import World` the package's `__init__`)."""
    paths = {module_name(path): path for path in PACKAGE.rglob('*.py')}
    edges: dict[str, set[str]] = {}
    for name, path in paths.items():
        package = name if path.name == '__init__.py' else name.rpartition('.')[0]
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ''
                if node.level:   # relative: from the module's package, one level up per dot beyond the first
                    up = package.rsplit('.', node.level - 1)[0] if node.level > 1 else package
                    base = f'{up}.{base}' if base else up
                targets = [f'{base}.{alias.name}' if f'{base}.{alias.name}' in paths else base for alias in node.names]
            elif isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                continue
            edges.setdefault(name, set()).update(target for target in targets if target in paths and target != name)
    return edges


def circles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected parts of more than one module (Tarjan), each sorted: every module of one reaches every
    other, so each is an import circle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        for nxt in sorted(edges.get(module, ())):
            if nxt not in index:
                visit(nxt)
                low[module] = min(low[module], low[nxt])
            elif nxt in stack:
                low[module] = min(low[module], index[nxt])
        if low[module] == index[module]:
            part = []
            while not part or part[-1] != module:
                part.append(stack.pop())
            if len(part) > 1:
                found.append(sorted(part))

    for module in sorted(edges):
        if module not in index:
            visit(module)
    return sorted(found)


def test_no_module_is_in_an_import_circle():
    """Inside a sub-package too: `bag.run_summary` and `bag.summary_text` imported each other, and `world.data`,
    `geometry`, `cells`, `raycast` and `collisions` went round (some under TYPE_CHECKING, which counts: the circle
    is in the design, whether or not Python runs it). The shared thing moves down, not into a function."""
    edges = module_imports()
    assert 'epuck_ros.world.data' in edges['epuck_ros.world']   # the package re-exports its modules' names
    assert circles(edges) == []


def test_circles_finds_a_circle_and_only_one():
    assert circles({'a': {'b'}, 'b': {'c'}, 'c': {'a', 'd'}, 'd': set(), 'e': {'d'}}) == [['a', 'b', 'c']]
