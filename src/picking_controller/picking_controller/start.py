"""The console script of this package: the node imported and run by :func:`picking_common.startup.quietly`."""

from picking_common.startup import quietly


def controller():
    return quietly('picking_controller.node:main')
