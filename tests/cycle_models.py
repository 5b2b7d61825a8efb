"""Small ODEs with periodic orbits of known properties, for tests/test_cycles.py (dense
Jacobians: contin accepts them for tiny problems, and the collocation evaluates one per
collocation point).

- Stuart-Landau (the Hopf normal form): x' = mu x - w y - x r^2, y' = w x + mu y - y r^2; for
  mu > 0 the circle r = sqrt(mu) with period 2 pi / w, nontrivial multiplier exp(-2 mu T).
- Bautin form: r' = r (mu + b r^2 - r^4), theta' = w (Cartesian); cycles r^2 = (b +- sqrt(b^2 +
  4 mu)) / 2, a fold of cycles at mu = -b^2 / 4, r^2 = b / 2; multiplier exp(T (2 b r^2 - 4 r^4)).
- Roessler (1976): x' = -y - z, y' = x + a y, z' = b + z (x - c); period doubling of its cycle
  near c = 2.83 for a = b = 0.2.
"""

from __future__ import annotations

import numpy as np


class StuartLandau:
    parameter_names = ("mu", "w")

    def residual(self, u, p):
        x, y = u
        r2 = x * x + y * y
        return np.array([p["mu"] * x - p["w"] * y - x * r2, p["w"] * x + p["mu"] * y - y * r2])

    def jacobian(self, u, p):
        x, y = u
        mu, w = p["mu"], p["w"]
        return np.array([[mu - 3 * x * x - y * y, -w - 2 * x * y], [w - 2 * x * y, mu - x * x - 3 * y * y]])

    def dresidual_dp(self, u, p, name):
        x, y = u
        return np.array([x, y]) if name == "mu" else np.array([-y, x])


class Bautin:
    parameter_names = ("mu", "b", "w")

    def residual(self, u, p):
        x, y = u
        r2 = x * x + y * y
        g = p["mu"] + p["b"] * r2 - r2 * r2
        return np.array([x * g - p["w"] * y, y * g + p["w"] * x])

    def jacobian(self, u, p):
        x, y = u
        r2 = x * x + y * y
        g = p["mu"] + p["b"] * r2 - r2 * r2
        gr = p["b"] - 2 * r2  # dg/d(r^2)
        w = p["w"]
        return np.array([[g + 2 * x * x * gr, 2 * x * y * gr - w],
                         [2 * x * y * gr + w, g + 2 * y * y * gr]])

    def dresidual_dp(self, u, p, name):
        x, y = u
        r2 = x * x + y * y
        return {"mu": np.array([x, y]), "b": np.array([x * r2, y * r2]), "w": np.array([-y, x])}[name]


class Roessler:
    parameter_names = ("a", "b", "c")

    def residual(self, u, p):
        x, y, z = u
        return np.array([-y - z, x + p["a"] * y, p["b"] + z * (x - p["c"])])

    def jacobian(self, u, p):
        x, y, z = u
        return np.array([[0.0, -1.0, -1.0], [1.0, p["a"], 0.0], [z, 0.0, x - p["c"]]])

    def dresidual_dp(self, u, p, name):
        x, y, z = u
        return {"a": np.array([0.0, y, 0.0]), "b": np.array([0.0, 0.0, 1.0]), "c": np.array([0.0, 0.0, -z])}[name]


class DrivenPair:
    """Stuart-Landau (x, y) driving a linear-plus-cubic oscillator (u, v):
    u' = (alpha - k r^2) u - w2 v - u s^2, v' = w2 u + (alpha - k r^2) v - v s^2 (r^2 = x^2 + y^2,
    s^2 = u^2 + v^2).  On the cycle r^2 = mu, (u, v) = 0 the (u, v) multipliers are
    exp((alpha - k mu) T +- i w2 T), T = 2 pi / w: a Neimark-Sacker point at mu = alpha / k."""

    parameter_names = ("mu", "w", "alpha", "k", "w2")

    def residual(self, z, p):
        x, y, u, v = z
        r2, s2 = x * x + y * y, u * u + v * v
        g = p["alpha"] - p["k"] * r2 - s2
        return np.concatenate([StuartLandau().residual(z[:2], p), [g * u - p["w2"] * v, p["w2"] * u + g * v]])

    def jacobian(self, z, p):
        x, y, u, v = z
        r2, s2 = x * x + y * y, u * u + v * v
        g = p["alpha"] - p["k"] * r2 - s2
        k, w2 = p["k"], p["w2"]
        out = np.zeros((4, 4))
        out[:2, :2] = StuartLandau().jacobian(z[:2], p)
        out[2] = [-2 * k * x * u, -2 * k * y * u, g - 2 * u * u, -w2 - 2 * u * v]
        out[3] = [-2 * k * x * v, -2 * k * y * v, w2 - 2 * u * v, g - 2 * v * v]
        return out

    def dresidual_dp(self, z, p, name):
        x, y, u, v = z
        r2 = x * x + y * y
        if name in ("mu", "w"):
            return np.concatenate([StuartLandau().dresidual_dp(z[:2], p, name), [0.0, 0.0]])
        return {"alpha": np.array([0.0, 0.0, u, v]), "k": np.array([0.0, 0.0, -r2 * u, -r2 * v]),
                "w2": np.array([0.0, 0.0, -v, u])}[name]


class TwoHopfLandau:
    """Stuart-Landau with mu = p (1 - p): Hopf points at p = 0 and p = 1 joined by the cycles
    r^2 = p (1 - p), period 2 pi / w (the branch from one Hopf point ends at the other)."""

    parameter_names = ("p", "w")

    def _sl(self, p):
        return {"mu": p["p"] * (1 - p["p"]), "w": p["w"]}

    def residual(self, u, p):
        return StuartLandau().residual(u, self._sl(p))

    def jacobian(self, u, p):
        return StuartLandau().jacobian(u, self._sl(p))

    def dresidual_dp(self, u, p, name):
        if name == "w":
            return StuartLandau().dresidual_dp(u, self._sl(p), "w")
        return (1 - 2 * p["p"]) * StuartLandau().dresidual_dp(u, self._sl(p), "mu")


class CyclePitchfork:
    """Stuart-Landau (x, y) (w = 1) with a transverse z: z' = (beta - r^2) z - q z^2 - z^3
    (r^2 = x^2 + y^2).  The cycle r^2 = mu, z = 0, T = 2 pi has the z-multiplier
    exp(2 pi (beta - mu)), through +1 at mu = beta: a branch point of cycles (BPC).  The cycles
    bifurcating there have r^2 = mu, z^2 + q z = beta - mu, period 2 pi: with q = 0 (symmetric under
    z -> -z) a pitchfork, z = +-sqrt(beta - mu) for mu < beta; with q != 0 a transcritical point,
    the bifurcated branch turning at a fold of cycles mu = beta + q^2 / 4, z = -q / 2."""

    parameter_names = ("mu", "beta", "q")

    def residual(self, u, p):
        x, y, z = u
        r2 = x * x + y * y
        return np.array([p["mu"] * x - y - x * r2, x + p["mu"] * y - y * r2,
                         (p["beta"] - r2) * z - p["q"] * z * z - z**3])

    def jacobian(self, u, p):
        x, y, z = u
        r2 = x * x + y * y
        mu = p["mu"]
        return np.array([[mu - 3 * x * x - y * y, -1.0 - 2 * x * y, 0.0],
                         [1.0 - 2 * x * y, mu - x * x - 3 * y * y, 0.0],
                         [-2 * x * z, -2 * y * z, p["beta"] - r2 - 2 * p["q"] * z - 3 * z * z]])

    def dresidual_dp(self, u, p, name):
        x, y, z = u
        return {"mu": np.array([x, y, 0.0]), "beta": np.array([0.0, 0.0, z]), "q": np.array([0.0, 0.0, -z * z])}[name]


class MoebiusPair:
    """Stuart-Landau (x, y) (w = 1) with a transverse w = (u, v) that turns by half the cycle's angle
    per period: w' = (1/2 + a) J w + b w + g [[-y, x], [x, y]] w - |w|^2 w (J the rotation by pi/2).
    On the cycle r^2 = mu, w = 0 (T = 2 pi) the frame turned by -theta/2 makes it s' = B s with
    B = b I + a J + g sqrt(mu) [[0, 1], [1, 0]], so the w-multipliers are -exp(2 pi (b +- sqrt(g^2 mu - a^2))):
    a complex pair of modulus exp(2 pi b) for mu < a^2 / g^2 that turns real there, and (b < 0) a
    period doubling at mu = (a^2 + b^2) / g^2."""

    parameter_names = ("mu", "a", "b", "g")

    def residual(self, z, p):
        x, y, u, v = z
        s2 = u * u + v * v
        om, b, g = 0.5 + p["a"], p["b"], p["g"]
        return np.concatenate([StuartLandau().residual(z[:2], {"mu": p["mu"], "w": 1.0}),
                               [-om * v + b * u + g * (-y * u + x * v) - s2 * u,
                                om * u + b * v + g * (x * u + y * v) - s2 * v]])

    def jacobian(self, z, p):
        x, y, u, v = z
        s2 = u * u + v * v
        om, b, g = 0.5 + p["a"], p["b"], p["g"]
        out = np.zeros((4, 4))
        out[:2, :2] = StuartLandau().jacobian(z[:2], {"mu": p["mu"], "w": 1.0})
        out[2] = [g * v, -g * u, b - g * y - s2 - 2 * u * u, -om + g * x - 2 * u * v]
        out[3] = [g * u, g * v, om + g * x - 2 * u * v, b + g * y - s2 - 2 * v * v]
        return out

    def dresidual_dp(self, z, p, name):
        x, y, u, v = z
        if name == "mu":
            return np.array([x, y, 0.0, 0.0])
        return {"a": np.array([0.0, 0.0, -v, u]), "b": np.array([0.0, 0.0, u, v]),
                "g": np.array([0.0, 0.0, -y * u + x * v, x * u + y * v])}[name]
