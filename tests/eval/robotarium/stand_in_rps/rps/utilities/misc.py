"""The stand-in's ``rps.utilities.misc`` (the pose checkers a script may use)."""

import numpy as np


def create_at_pose(position_error=0.05, rotation_error=0.2):
    def at_pose(states, poses):
        d = np.linalg.norm(states[:2] - poses[:2], axis=0)
        e = np.abs(np.arctan2(np.sin(states[2] - poses[2]), np.cos(states[2] - poses[2])))
        done = np.nonzero((d <= position_error) & (e <= rotation_error))[0]
        return done.size == states.shape[1], done

    return at_pose


def create_at_position(position_error=0.05):
    def at_position(states, points):
        done = np.nonzero(np.linalg.norm(states[:2] - points[:2], axis=0) <= position_error)[0]
        return done.size == states.shape[1], done

    return at_position
