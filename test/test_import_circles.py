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
