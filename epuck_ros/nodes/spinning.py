"""Spinning a node until Ctrl-C or SIGTERM, the Jazzy way, without a spurious error at the end."""
from __future__ import annotations

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


def spin_until_shutdown(node: Node) -> None:
    """`rclpy.spin` that ends quietly on Ctrl-C / SIGTERM.

    rclpy's signal handler shuts the context down wherever the main thread is, possibly inside a
    callback that is about to publish; that publish then fails. Such a failure, once the context is
    gone, is part of shutting down, not an error; any failure while the context is alive is re-raised.
    """
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if node.context.ok():
            raise
