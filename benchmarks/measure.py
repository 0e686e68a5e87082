"""What the benchmarks read of the processes they start (imported by the scripts next to it)."""
from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from epuck_ros.bringup.monitor import REQUEST_RETRY   # the resume is asked again as `bringup` asks it


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU seconds a process has used so far (Linux /proc); None once it is gone."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def resume(parameters: Any, spin_until_done: Callable[[Any, float], None], attempts: int = 30) -> bool:
    """Set the simulator's `paused` to false through `parameters` (an AsyncParameterClient), asking again every
    REQUEST_RETRY; `spin_until_done(future, timeout)` spins the bench's node. True once the simulator answered."""
    from rclpy.parameter import Parameter
    for _ in range(attempts):
        future = parameters.set_parameters([Parameter('paused', value=False)])
        spin_until_done(future, REQUEST_RETRY)
        if future.done():
            return True
    return False
