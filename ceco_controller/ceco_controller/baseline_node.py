"""baseline_node: the production automatic climate control law as a node.

The law: PI with anti-windup on the cabin air temperature (ceco_core.acc_law), with the
same topics, timing modes, checks and lifecycle as mpc_node (it reuses its
node class with the strategy fixed to ``baseline``; it uses no preview for
its decisions but waits for them in lockstep so both nodes step alike).
"""

from __future__ import annotations

from ceco_controller.mpc_node import ControllerNode
from ceco_ros.node_main import run_node


class BaselineNode(ControllerNode):
    """mpc_node's class with the strategy fixed to ``baseline``."""

    def __init__(self):
        super().__init__('baseline_node', fixed_strategy='baseline')


def main(args=None) -> int:
    """Entry point of the baseline_node executable."""
    return run_node(BaselineNode, args, 'baseline_node')


if __name__ == '__main__':
    raise SystemExit(main())
