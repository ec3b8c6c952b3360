"""UR5e motion planning cores: timed joint trajectories, capsule collision checks, boll approach plans."""
