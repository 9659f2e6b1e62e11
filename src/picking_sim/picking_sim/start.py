"""The console scripts of this package: each node imported and run by :func:`picking_common.startup.quietly`."""

from picking_common.startup import quietly


def sim():
    return quietly('picking_sim.node:main')


def state_publisher():
    return quietly('picking_sim.state_publisher:main')
