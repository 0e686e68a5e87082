"""Spinning nodes until Ctrl-C or SIGTERM, ending cleanly on the first signal, every time.

rclpy's own signal handlers shut the context down from the signal, wherever the main thread is: inside
`take_message`, or inside a callback about to publish. Under load that ended nodes with a pybind11
RuntimeError (exit 1), and once the context is gone a node can no longer say goodbye (a behaviour's last
zero wheel command). Here the signals only raise a flag; the spin loop sees it within `SIGNAL_LATENCY`,
returns with the context alive, and the caller's `finally` publishes what it must, destroys its nodes and
calls `rclpy.try_shutdown()` (exit code 0).
"""
from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable

from rclpy.context import Context
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions, get_current_signal_handlers_options, uninstall_signal_handlers

from epuck_ros.exit_codes import ignore_ctrl_c_at_exit

SIGNAL_LATENCY = 0.1
"""Wall seconds the spin loop waits for work at most before looking at the flag (a signal does not wake rcl_wait)."""

_requested = threading.Event()


def _request_shutdown(signum: int, frame: object) -> None:
    _requested.set()


def handle_shutdown_signals() -> None:
    """From now on SIGINT and SIGTERM only ask for a shutdown (`shutdown_requested()`); call after `rclpy.init`.
    Once the program has returned, Ctrl-C is ignored (`exit_codes.ignore_ctrl_c_at_exit`)."""
    if get_current_signal_handlers_options() != SignalHandlerOptions.NO:
        uninstall_signal_handlers()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _request_shutdown)
    ignore_ctrl_c_at_exit()


def _raise_keyboard_interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def interrupt_on_signals() -> None:
    """From now on SIGINT and SIGTERM raise KeyboardInterrupt in the main thread, for a program whose main thread
    works outside any spin (teleop's keyboard, `bag play`'s publishing); call after `rclpy.init(...,
    signal_handler_options=SignalHandlerOptions.NO)`. Its `finally` then ends cleanly with the context still up: under
    rclpy's own handlers the context went down while `bag play` was publishing, and it died of SIGSEGV (a suite
    run beside a busy loop per core)."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _raise_keyboard_interrupt)


def shutdown_requested() -> bool:
    return _requested.is_set()


def spin_until_shutdown(*nodes: Node, until: Callable[[], bool] | None = None,
                        executor_type: Callable[..., Executor] = SingleThreadedExecutor) -> None:
    """Spin `nodes` on one executor until SIGINT / SIGTERM, the context's shutdown, or `until()` is true.

    Returns with the context still usable (unless something else shut it down). A failure inside a callback
    once the context is gone is part of someone else shutting it down, not an error; any other is re-raised.
    `executor_type` is called with `context=`: SingleThreadedExecutor, or rclpy's EventsExecutor.
    """
    handle_shutdown_signals()
    context: Context = nodes[0].context
    executor = executor_type(context=context)
    for node in nodes:
        executor.add_node(node)
    try:
        while not _requested.is_set() and context.ok() and not (until is not None and until()):
            executor.spin_once(timeout_sec=SIGNAL_LATENCY)
    except ExternalShutdownException:
        pass
    except Exception:
        if context.ok():
            raise
    finally:
        for node in nodes:
            executor.remove_node(node)
        executor.shutdown(timeout_sec=0.0)


def end_process(code: int) -> None:
    """End this process now with `code`, its output flushed: no thread left running keeps it alive (a Webots
    script's, as Webots ends a controller) and no DDS entity is destroyed one by one (a swarm's take seconds); the
    other participants drop ours after the lease of the package's DDS profile."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(code)
