"""The console script of the Foxglove bridge, which picking-stack starts as a node: imported and run by
:func:`picking_common.startup.quietly`."""

from picking_common.startup import quietly


def foxglove():
    return quietly('picking_bringup.foxglove:main')
