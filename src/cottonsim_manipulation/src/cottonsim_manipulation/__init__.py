"""Robot-side arm code for the harvest: planning (trajectories, collisions, approaches) and harvest rules."""
