"""The numpy actor's arithmetic: exact products (so the summation order, hence the BLAS kernel,
cannot matter) and a tanh from + - * / alone, both close to the float64 reference."""

import numpy as np
import pytest

from boids_env.policies import exact
from boids_env.policies.mlp_actor import MLPActor


def layer_inputs(seed, rows=9, inputs=99, outputs=128):
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 2, (rows, inputs)).astype(np.float32)
    x[0] = 0.0  # an all-zero row
    x[1, ::3] *= 1e-6  # a row of very different magnitudes
    x[2, inputs // 2] = 10.0  # the observations' largest coordinates
    w = rng.normal(0, 0.3, (inputs, outputs)).astype(np.float32)
    w[:, 3] = 0.0  # an all-zero column
    w[::7, 4] *= 1e-5
    b = rng.normal(0, 0.1, outputs).astype(np.float32)
    return x.astype(np.float64), w, b


@pytest.mark.parametrize("inputs", [1, 2, 99, 128, 300])
def test_the_exact_product_equals_the_float64_reference(inputs):
    x, w, b = layer_inputs(inputs, inputs=inputs)
    out = exact.ExactLinear(w, b)(x)
    reference = x @ w.astype(np.float64) + b
    scale = np.abs(x).max(axis=1, keepdims=True) * np.abs(w).max(axis=0) * inputs + 1.0
    err = np.abs(out - reference)
    assert (err <= 1e-8 * scale).all(), f"worst error {err.max()} at {np.argmax(err)}"
    assert np.array_equal(out[0], np.broadcast_to(b.astype(np.float64), out[0].shape))


def test_the_product_does_not_depend_on_the_summation_order():
    # The inputs in another order sum the products in another order: a float64 matrix product
    # of the plain values then differs in the last bits, the exact one does not.
    x, w, b = layer_inputs(3)
    order = np.random.default_rng(4).permutation(x.shape[1])
    plain = x @ w.astype(np.float64)
    assert not np.array_equal(plain, x[:, order] @ w[order].astype(np.float64)), \
        "this check needs data where the plain product depends on the order"
    out = exact.ExactLinear(w, b)(x)
    assert np.array_equal(out, exact.ExactLinear(w[order], b)(x[:, order]))
    # and one product at a time, in Python, gives the same bits as BLAS
    rows = [exact.ExactLinear(w, b)(x[i:i + 1]) for i in range(len(x))]
    assert np.array_equal(out, np.concatenate(rows))


def test_the_weight_bits_keep_every_partial_sum_below_2_to_the_53():
    for inputs in (1, 2, 3, 99, 128, 129, 4096):
        bits = exact.weight_bits(inputs)
        assert inputs * 2 ** (exact.SLICE_BITS + bits) <= 2 ** 53, inputs
        assert 2 * inputs * 2 ** (exact.SLICE_BITS + bits) > 2 ** 53, f"{inputs}: bits wasted"
    with pytest.raises(ValueError, match="at least one input"):
        exact.weight_bits(0)


def test_tanh_matches_the_float64_reference():
    y = np.concatenate([np.linspace(-25, 25, 20001), [0.0, -0.0, 1e-300, -1e-12, 19.99, 20.0,
                                                      20.01, 700.0, -np.inf, np.inf]])
    out = exact.tanh(y)
    np.testing.assert_allclose(out, np.tanh(y), rtol=0, atol=2e-12)
    assert np.signbit(out[20002]) and not np.signbit(out[20001]), "the sign of zero is kept"
    assert np.isnan(exact.tanh(np.array([np.nan]))).all()


def test_a_relu_actor_and_a_tanh_actor_equal_their_float64_forward_pass():
    rng = np.random.default_rng(5)
    w = [rng.normal(0, 0.3, (16, 7)), rng.normal(0, 0.3, (16, 16)), rng.normal(0, 0.3, (2, 16))]
    b = [rng.normal(0, 0.1, 16), rng.normal(0, 0.1, 16), rng.normal(0, 0.1, 2)]
    w = [m.astype(np.float32) for m in w]
    b = [v.astype(np.float32) for v in b]
    obs = rng.normal(0, 2, (11, 7)).astype(np.float32)
    for name, act in (("tanh", np.tanh), ("relu", lambda v: np.maximum(v, 0.0))):
        x = obs.astype(np.float64)
        for m, v in zip(w[:-1], b[:-1], strict=True):
            x = act(x @ m.T.astype(np.float64) + v)
        expected = np.clip(x @ w[-1].T.astype(np.float64) + b[-1], -0.5, 0.5)
        out = MLPActor(w, b, name, [-0.5, -0.5], [0.5, 0.5]).act_batch(obs)
        assert out.dtype == np.float32
        np.testing.assert_allclose(out, expected, rtol=0, atol=1e-7, err_msg=name)
