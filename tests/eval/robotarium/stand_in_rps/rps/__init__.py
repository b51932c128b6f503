"""Stand-in for the Robotarium's ``rps`` (tests only; see the README beside it)."""
