"""`webots_controller SCRIPT.py`: a Webots-style controller script over ROS (`webots.runner`) or, with
`--headless`, against the pure core in this process (`experiments.headless_cli`).

The command sits above both: the experiments run scripts through `webots` (a headless trial's seats), so nothing
in `webots` may import `experiments`.
"""
from __future__ import annotations

import os
import sys

HEADLESS = '--headless'


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else argv
    # Each way imports only its own half: a script's process starts once per robot, and the other half's imports
    # (the bag and experiments modules, or ROS's) took a fifth of its start.
    if HEADLESS not in args:
        from epuck_ros.webots import runner
        runner.main(args)
        return
    from epuck_ros.experiments import headless_cli
    from epuck_ros.ros.spinning import end_process
    code = 0
    try:
        headless_cli.main([arg for arg in args if arg != HEADLESS])
    except SystemExit as end:
        code = end.code if isinstance(end.code, int) else 1
    except BrokenPipeError:   # `... | head -1`: the reader has all it wants (it ended in a traceback)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())   # what is still buffered goes nowhere
    end_process(code)   # not SystemExit: a thread the script left running would keep the process alive


if __name__ == '__main__':
    main()
