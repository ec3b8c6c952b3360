"""The harvest evaluation: reachability of the bolls from the route, the harvest figures, the field plot."""
