"""Localisation cores: AMCL (odometry motion model, likelihood-field laser model, KLD particle filter)."""
