"""ROS plumbing the three picking-arm nodes share, with no maths and no planner knowledge.

- :mod:`.run`: running a node (init, spin, signals, stack dumps on ``SIGUSR1``);
- :mod:`.loop`: the real-time periodic loop (absolute deadlines, phase, SCHED_FIFO, one stall policy)
  and :mod:`.loop_stats`, its statistics;
- :mod:`.topics`: QoS profiles and the newest message of a topic;
- :mod:`.status`: status levels and DiagnosticStatus helpers;
- :mod:`.joint_state`: the JointState layout;
- :mod:`.codec`: messages as CDR bytes (:mod:`.cdr`), with the fallback to the message classes inside.
"""
