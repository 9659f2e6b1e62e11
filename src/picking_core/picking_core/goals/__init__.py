"""The planner's goals, with no ROS in them: what a goal asks for (:mod:`.requests`), where its plan starts
(:mod:`.start`), its plan (:mod:`.planning`), its life once sent (:mod:`.lifecycle`), and the flow that joins
them (:mod:`.runner`)."""
