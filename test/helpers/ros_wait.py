"""Waiting helpers for integration tests: wait for the other side, never sleep a fixed time."""
from __future__ import annotations

import time
from typing import Callable

import rclpy


def spin_until(node, condition: Callable[[], bool], timeout: float, step: float = 0.05) -> bool:
    """Spin ``node`` until ``condition()`` is true or ``timeout`` seconds passed."""
    deadline = time.monotonic() + timeout
    executor = rclpy.executors.SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while time.monotonic() < deadline:
            if condition():
                return True
            executor.spin_once(timeout_sec=step)
        return condition()
    finally:
        executor.remove_node(node)


def call_service(node, client, request, timeout: float):
    """Call a service and wait for the response (None on timeout)."""
    if not client.wait_for_service(timeout_sec=timeout):
        return None
    future = client.call_async(request)
    spin_until(node, future.done, timeout)
    return future.result() if future.done() else None
