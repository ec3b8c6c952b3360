"""Run-time bookkeeping of the Cotton-Eye nodes: processing rates and the health of their inputs."""
