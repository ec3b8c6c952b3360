"""The harvest as an experiment on the route: its route, its record (harvest.json), the boll outcomes."""
