"""The console scripts of this package: each node imported and run by :func:`picking_common.startup.quietly`."""

from picking_common.startup import quietly


def planner():
    return quietly('picking_planner.node:main')


def harvester():
    return quietly('picking_planner.harvester:main')
