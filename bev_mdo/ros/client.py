"""A ROS evaluator for one-off use from the command line (`evaluate`, `sensitivity`, `sweep`, `check-totals`): it
joins the config's ROS domain (localhost discovery unless the config opts in to more), waits for every discipline
of the config to be discovered, and releases its own rclpy context on close()."""
from __future__ import annotations

import os
from typing import Any, Mapping


def apply_ros_environment(ros: Mapping[str, Any]) -> None:
    """Put the config's domain and discovery settings into this process's environment (before rclpy.init)."""
    from bev_mdo.ros_settings import ros_environment

    env = ros_environment(ros)
    for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER",
              "FASTRTPS_DEFAULT_PROFILES_FILE"):
        if k in env:
            os.environ[k] = env[k]
        else:
            os.environ.pop(k, None)


class _OwnedRosEvaluator:
    """A RosEvaluator plus the context and node it runs on."""

    closed = False

    def __init__(self, config: Mapping[str, Any], node_name: str, run_id: str | None = None):
        import rclpy

        from bev_mdo.config import RunConfig
        from bev_mdo.ros.coordinator_node import CoordinatorNode
        from bev_mdo.ros_settings import choose_domain

        config = RunConfig.of(config)
        # the domain the config states, else ROS_DOMAIN_ID, else 77
        ros = {**config.ros, "domain_id": choose_domain(config["ros"])[0]}
        apply_ros_environment(ros)
        self._ctx = rclpy.context.Context()
        rclpy.init(context=self._ctx)
        try:
            self._node = CoordinatorNode(config, run_id, context=self._ctx, node_name=node_name)
            self.inner = self._node.evaluator
            self.inner.wait_for_disciplines(list(config.names), ros["discovery_wait_s"])
        except BaseException:
            rclpy.shutdown(context=self._ctx)
            raise
        self.specs = self.inner.specs
        self.counts = self.inner.counts
        self.dropped = self.inner.dropped  # results and declarations dropped, by reason
        self.signed = self.inner.signer is not None

    def evaluate(self, calls, partials: bool = False):
        return self.inner.evaluate(calls, partials=partials)

    def close(self) -> None:
        """Bounded, in the CLI at the exit (stacks.teardown): a participant hung in Fast DDS held a sweep."""
        import rclpy

        from bev_mdo.stacks import teardown

        if self._ctx.ok() and not self.closed:
            self.closed, inner, node, ctx = True, self.inner, self._node, self._ctx
            teardown(lambda: (inner.close(), node.destroy_node(), rclpy.shutdown(context=ctx)))


def make_ros_evaluator(config: Mapping[str, Any], node_name: str = "bev_mdo_client", run_id: str | None = None):
    """An evaluator over the running discipline nodes of `config` (raises naming any missing one);
    `run_id`: the run the nodes were launched for (launch.OwnSuite), default a fresh one."""
    return _OwnedRosEvaluator(config, node_name, run_id)

