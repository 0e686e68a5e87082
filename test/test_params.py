"""Parameter tables shared by the nodes: --help, typos, integers for floats, values checked before rclpy starts."""
from __future__ import annotations

from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter

from epuck_ros.ros.params import ParamSpec, ParameterError, Usage, check_arguments, declare_parameters, \
    prepare_arguments

SPECS = [
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second', (0.0, 1e4)),
    ParamSpec('goal_distance', 0.1, 'metres to drive', (0.001, 10.0), read_only=True),
    ParamSpec('seed', 0, 'seed of every random draw', (0, 2**31 - 1), read_only=True),
    ParamSpec('noise', True, 'sensor noise on or off'),
    ParamSpec('world', '', 'world file'),
]
USAGE = Usage('demo', 'Does a demonstration.', 'demo --ros-args -p goal_distance:=0.3')


def ros(*assignments: str) -> list[str]:
    return ['demo', '--ros-args', *[arg for a in assignments for arg in ('-p', a)]]


def test_integers_for_float_parameters_become_float_literals():
    args = check_arguments(ros('real_time_factor:=0', 'goal_distance:=1', 'seed:=4'), SPECS)
    assert args == ros('real_time_factor:=0.0', 'goal_distance:=1.0', 'seed:=4')


@pytest.mark.parametrize('assignment, message', [
    ('goal_distnace:=0.3', "unknown parameter 'goal_distnace' (did you mean goal_distance?)"),
    ('seeed:=3', "unknown parameter 'seeed' (did you mean seed?)"),
    ('seed:=abc', 'seed: expected an integer, got abc'),
    ('seed:=1.5', 'seed: expected an integer'),
    ('real_time_factor:=-1', 'real_time_factor: -1.0 is out of range [0, 10000]'),
    ('real_time_factor:=nan', 'real_time_factor: nan is out of range'),
    ('real_time_factor:=', 'real_time_factor: empty value'),
    ('noise:=3', 'noise: expected a boolean'),
    ('goal_distance:=' + '9' * 400, 'goal_distance: '),
])
def test_refused_overrides_name_the_parameter(assignment, message):
    with pytest.raises(ParameterError) as caught:
        check_arguments(ros(assignment), SPECS)
    assert message in str(caught.value)


def test_rclpy_parameters_and_other_nodes_overrides_pass_through():
    args = ros('use_sim_time:=true', 'qos_overrides./clock.publisher.depth:=5', 'other:whatever:=1', 'world:=3')
    assert check_arguments(args, SPECS) == [*args[:-1], "world:='3'"]  # a world named 3 stays a string


def test_params_file_is_checked_too(tmp_path: Path):
    good, bad = tmp_path / 'good.yaml', tmp_path / 'bad.yaml'
    good.write_text('/**:\n  ros__parameters:\n    real_time_factor: 2.0\n    use_sim_time: true\n')
    bad.write_text('demo:\n  ros__parameters:\n    seeed: 3\n')
    check_arguments(['demo', '--ros-args', '--params-file', str(good)], SPECS)
    with pytest.raises(ParameterError, match='did you mean seed'):
        check_arguments(['demo', '--ros-args', '--params-file', str(bad)], SPECS)


def test_help_lists_every_parameter_and_exits_0(capsys):
    with pytest.raises(SystemExit) as caught:
        prepare_arguments(['demo', '--help', '--ros-args', '-p', 'seed:=1'], SPECS, USAGE)
    assert caught.value.code == 0
    out = capsys.readouterr().out
    assert 'Does a demonstration.' in out and USAGE.example in out
    for spec in SPECS:
        line = next(line for line in out.splitlines() if line.strip().startswith(spec.name + ' '))
        assert spec.description in line
    assert '0 .. 2147483647' in out and '0.1' in out


def test_bad_override_exits_2_with_one_line(capsys):
    with pytest.raises(SystemExit) as caught:
        prepare_arguments(ros('goal_distnace:=0.3'), SPECS, USAGE)
    assert caught.value.code == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        "demo: unknown parameter 'goal_distnace' (did you mean goal_distance?)"]


def test_arguments_outside_ros_args_are_refused_unless_the_executable_reads_them(capsys):
    with pytest.raises(SystemExit) as caught:
        prepare_arguments(['demo', '-p', 'seed:=3'], SPECS, USAGE)
    assert caught.value.code == 2 and '--ros-args' in capsys.readouterr().err
    assert prepare_arguments(['demo', '--robots', 'a'], SPECS, USAGE, own_options=True) == ['demo', '--robots', 'a']


def test_declared_parameters_have_descriptors_and_take_integers_for_floats_at_run_time():
    context = Context()
    rclpy.init(args=check_arguments(ros('real_time_factor:=0', 'seed:=7'), SPECS), context=context)
    try:
        node = Node('demo', context=context)
        values = declare_parameters(node, SPECS)
        assert values['real_time_factor'] == 0.0 and isinstance(values['real_time_factor'], float)
        assert values['seed'] == 7 and values['world'] == ''
        seed = node.describe_parameter('seed')
        assert seed.read_only and seed.integer_range[0].to_value == 2**31 - 1
        assert node.describe_parameter('real_time_factor').floating_point_range[0].to_value == 1e4
        assert node.set_parameters([Parameter('real_time_factor', value=3)])[0].successful
        assert node.get_parameter('real_time_factor').value == 3.0
        assert isinstance(node.get_parameter('real_time_factor').value, float)
        assert not node.set_parameters([Parameter('real_time_factor', value=-1)])[0].successful
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
