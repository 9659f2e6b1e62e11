"""An action client safe to use from a thread other than the one spinning it."""

from __future__ import annotations

import threading

from rclpy.action import ActionClient as _RclpyActionClient


class ActionClient(_RclpyActionClient):
    """rclpy's action client, whose requests may be sent from any thread.

    rclpy matches an answer (goal accepted, result, cancel) to its request by a sequence number it records only
    after the request went out. An executor spinning on another thread can take the answer in between; rclpy then
    drops it as "unexpected" and the request's future never completes (ros2/rclpy#1123, fixed in releases newer
    than the Jazzy wheels). Here sending a request and recording it is one step that taking answers waits for.
    """

    def __init__(self, *args, **kwargs):
        self._requests = threading.RLock()
        super().__init__(*args, **kwargs)

    def send_goal_async(self, *args, **kwargs):
        with self._requests:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle):
        with self._requests:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle):
        with self._requests:
            return super()._get_result_async(goal_handle)

    def take_data(self):
        with self._requests:
            return super().take_data()
