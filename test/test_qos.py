"""The QoS profiles are built in one place (`ros/qos.py`), and the one rule the recorder and the Foxglove bridge
use to read a topic whatever its publishers offer (`qos.matching`)."""
from __future__ import annotations

import ast
from pathlib import Path

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from epuck_ros.nodes.foxglove_node import MAX_DEPTH, reading_qos
from epuck_ros.ros.qos import matching
from epuck_ros.nodes.record_node import SUBSCRIPTION_DEPTH, subscription_qos

PACKAGE = Path(__file__).resolve().parents[1] / 'epuck_ros'
RELIABLE_LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(depth=300, reliability=ReliabilityPolicy.RELIABLE)
BEST_EFFORT = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)


def policies(qos: QoSProfile) -> tuple:
    return qos.history, qos.depth, qos.reliability, qos.durability


def test_a_reader_is_reliable_and_latched_only_when_every_publisher_is():
    assert policies(matching([RELIABLE_LATCHED, RELIABLE_LATCHED], 7)) == (
        HistoryPolicy.KEEP_LAST, 7, ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)
    assert policies(matching([RELIABLE_LATCHED, RELIABLE], 7)) == (
        HistoryPolicy.KEEP_LAST, 7, ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    assert policies(matching([RELIABLE, BEST_EFFORT], 7)) == (
        HistoryPolicy.KEEP_LAST, 7, ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
    assert policies(matching([], 7)) == (
        HistoryPolicy.KEEP_LAST, 7, ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)


def test_keep_all_only_for_a_reliable_reader():
    """A best-effort reader KEEP_ALL would hold samples no publisher waits for."""
    assert matching([RELIABLE], 7, keep_all=True).history == HistoryPolicy.KEEP_ALL
    assert matching([RELIABLE, BEST_EFFORT], 7, keep_all=True).history == HistoryPolicy.KEEP_LAST


def test_the_recorder_and_the_bridge_read_by_the_same_rule():
    """The recorder keeps all of a reliable topic (the simulator waits for it), the bridge as deep as the
    publishers' histories together, within MAX_DEPTH; reliability and durability by `matching` for both."""
    for offered in ([RELIABLE_LATCHED], [RELIABLE, RELIABLE_LATCHED], [RELIABLE, BEST_EFFORT], [BEST_EFFORT]):
        recorder, bridge = subscription_qos(offered), reading_qos(offered)
        shared = matching(offered, 1)
        assert (recorder.reliability, recorder.durability) == (shared.reliability, shared.durability)
        assert (bridge.reliability, bridge.durability) == (shared.reliability, shared.durability)
        assert recorder.depth == SUBSCRIPTION_DEPTH
        assert bridge.history == HistoryPolicy.KEEP_LAST
    assert subscription_qos([RELIABLE]).history == HistoryPolicy.KEEP_ALL
    assert reading_qos([RELIABLE]).depth == MAX_DEPTH
    assert reading_qos([RELIABLE_LATCHED, BEST_EFFORT]).depth == 6


def test_profiles_are_built_only_in_nodes_qos():
    """Profiles were built in 14 modules. Besides ros/qos.py only `ack_window.command_qos` builds one: its
    depth is the acknowledgement window's history (`history_steps`)."""
    builders = []
    for path in sorted(PACKAGE.rglob('*.py')):
        if 'examples' in path.parts:   # the user's reading: each example whole in itself
            continue
        tree = ast.parse(path.read_text(encoding='utf-8'))
        functions = {id(inner): node.name for node in ast.walk(tree)
                     if isinstance(node, ast.FunctionDef) for inner in ast.walk(node)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, 'id', getattr(node.func, 'attr', '')) == 'QoSProfile':
                builders.append(f'{path.relative_to(PACKAGE)}:{functions.get(id(node), "<module>")}')
            if isinstance(node, ast.alias) and node.name.startswith('qos_profile_'):   # rclpy's ready-made ones
                builders.append(f'{path.relative_to(PACKAGE)}:{node.name}')
    assert {builder for builder in builders if not builder.startswith('ros/qos.py:')} == {
        'ros/ack_window.py:command_qos'}
