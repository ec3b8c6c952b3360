"""move_base: the navigation state machine (goal -> plan -> control -> recovery -> result) and its recovery behaviours."""
