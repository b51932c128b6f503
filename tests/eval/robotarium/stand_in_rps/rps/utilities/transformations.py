"""The stand-in's single-integrator <-> unicycle mappings (rps 2.x names and shapes)."""

import numpy as np


def create_si_to_uni_dynamics(linear_velocity_gain=1, angular_velocity_limit=np.pi):
    """(2, N) SI velocities and (3, N) poses -> (2, N) (v, ω): v the projection on the
    heading, ω = limit · (angle from the heading to the velocity) / (π/2)."""
    if not isinstance(linear_velocity_gain, (int, float)) or linear_velocity_gain <= 0:
        raise AssertionError("linear_velocity_gain must be a positive number.")
    if not isinstance(angular_velocity_limit, (int, float)) or angular_velocity_limit < 0:
        raise AssertionError("angular_velocity_limit must be non-negative.")

    def si_to_uni(dxi, states):
        assert dxi.shape[0] == 2 and states.shape[0] == 3 and dxi.shape[1] == states.shape[1]
        c, s = np.cos(states[2]), np.sin(states[2])
        along = c * dxi[0] + s * dxi[1]
        across = -s * dxi[0] + c * dxi[1]
        return np.vstack([linear_velocity_gain * along,
                          angular_velocity_limit * np.arctan2(across, along) / (np.pi / 2)])

    return si_to_uni


def create_si_to_uni_mapping(projection_distance=0.05):
    """(si_to_uni_dyn, uni_to_si_states) about a point ``projection_distance`` ahead."""
    d = projection_distance

    def si_to_uni(dxi, states):
        c, s = np.cos(states[2]), np.sin(states[2])
        return np.vstack([c * dxi[0] + s * dxi[1], (-s * dxi[0] + c * dxi[1]) / d])

    def uni_to_si_states(states):
        return states[:2] + d * np.vstack([np.cos(states[2]), np.sin(states[2])])

    return si_to_uni, uni_to_si_states


def create_uni_to_si_mapping(projection_distance=0.05):
    """(uni_to_si_dyn, si_to_uni_states) about a point ``projection_distance`` ahead."""
    d = projection_distance

    def uni_to_si(dxu, states):
        c, s = np.cos(states[2]), np.sin(states[2])
        return np.vstack([c * dxu[0] - d * s * dxu[1], s * dxu[0] + d * c * dxu[1]])

    def si_to_uni_states(uni_states, si_states):
        return si_states[:2] - d * np.vstack([np.cos(uni_states[2]), np.sin(uni_states[2])])

    return uni_to_si, si_to_uni_states
