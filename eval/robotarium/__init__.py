"""``boids export robotarium``: the flock as a script for the Robotarium's testbed
(GRITSbots, its ``rps`` API): :mod:`.case` (the study's case scaled to the testbed, in our
env and in the script), :mod:`.script` (the script's text) and :mod:`.cli` (the command)."""
