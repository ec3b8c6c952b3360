"""Configuration files: reading them strictly."""
