"""Rules of the code (issue 28, house items): the latched QoS is made in one place, and module docstrings say
why, not what was measured (figures belong in the README's benchmark table)."""
from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / 'epuck_ros'
MEASURED = re.compile(r'\d[\d,.]*\s*(%|times\b|steps/s|MiB|MB|GB|KB|×|x real time)|about half|\d+ of \d+')
"""How a measured figure reads: a count of times, a share, a rate, a size, '<n> of <m>'."""


def modules() -> list[Path]:
    """The package's modules; the Webots-style example scripts are the user's reading, documented in the README."""
    return [path for path in sorted(PACKAGE.rglob('*.py')) if 'examples' not in path.parts]


def test_the_latched_profile_is_made_only_in_nodes_qos():
    """webots/link.py (LED_QOS) and testing/simulator.py made their own depth-1 transient-local profile."""
    makers = []
    for path in modules():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, 'id', getattr(node.func, 'attr', '')) == 'QoSProfile':
                text = ast.unparse(node)
                if 'TRANSIENT_LOCAL' in text and re.search(r'depth=1\b', text):
                    makers.append(f'{path.relative_to(PACKAGE)}:{node.lineno}')
    assert [maker.split(':')[0] for maker in makers] == ['ros/qos.py'], makers


def test_module_docstrings_hold_no_measured_figures():
    found = []
    for path in modules():
        doc = ast.get_docstring(ast.parse(path.read_text())) or ''
        found += [f'{path.relative_to(PACKAGE)}: {match.group(0)!r}' for match in MEASURED.finditer(doc)]
    assert found == [], found
