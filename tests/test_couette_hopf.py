"""gPCF travelling-mode Hopf point from the stability family (issue 12 sec. 1, contin.hopfscan).

With gravity (Fr = 200, nu = 0.3, e = 0.8, no-slip walls, cheb 48) the primary branch (bottom
plug forming) becomes unstable at k_x = 0.006 to the long-wave travelling mass mode at
H = 21.3121 (README, "Travelling modes of a wavenumber family"), with phase speed
omega / k_x = 0.4795, the kinematic-wave speed of the long-wave analysis.  The fast test traces
the primary branch only up to just past the HB and checks the located point against an
independent brentq on Re omega(H) of the tracked eigenvalue (dense scipy QZ of the
eigenproblem, the steady state re-solved at each H); the full scene run is the slow test.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp
from scipy.optimize import brentq

from contin.continuation import trace
from contin.hopfscan import locate_hopf
from contin.newton import newton
from contin.options import ContinuationOptions, StepOptions
from problems.couette.gravity import gravity_problem

KX = 0.006
H_DOC = 21.3121  # README / the gravity scene at Fr = 200, cheb 48
C_DOC = 0.4795


def _dense(m):
    return m.toarray() if sp.issparse(m) else np.asarray(m, dtype=float)


def test_gpcf_travelling_mode_hb_against_brentq_on_the_tracked_eigenvalue():
    pb = gravity_problem("cheb", 48)
    p = pb.params({"nu": 0.3, "e": 0.8, "Fr": 200.0, "H": 1.0})
    primary = trace(pb, pb.initial_guess(p), p, "H", ContinuationOptions(bounds={"H": (1.0, 20.9)}, max_steps=400))
    assert primary.status == "EP" and primary.params["H"][-1] == pytest.approx(20.9)
    near = trace(pb, primary.states[-1], {**p, "H": 20.9}, "H",
                 ContinuationOptions(bounds={"H": (20.9, 21.7)}, step=StepOptions(ds=0.2, ds_max=0.2), max_steps=20))
    scan = locate_hopf(pb, near, p, kx=KX)
    assert not scan.reasons
    (hb,) = scan.points
    H, omega = hb.params["H"], hb.data["omega"]
    assert hb.converged and hb.data["kx"] == KX
    assert abs(H - H_DOC) < 1e-3 and abs(omega / KX - C_DOC) < 1e-3

    # independent: Re of the eigenvalue nearest i omega, steady state by Newton at each H
    hs = near.params["H"]
    i = int(np.searchsorted(hs, H))
    lo, hi = hs[i - 1], hs[i]

    def state(h):
        w = (h - lo) / (hi - lo)
        guess = (1 - w) * near.states[i - 1] + w * near.states[i]
        res = newton(pb, guess, {**p, "H": h})
        assert res.converged
        return res.u

    def mode(h):
        a, b = pb.eigenproblem(state(h), {**p, "H": h}, kx=KX)
        al, be = la.eig(_dense(a), _dense(b), right=False, homogeneous_eigvals=True)
        fin = np.abs(be) > 1e-12 * np.abs(al)
        w = al[fin] / be[fin]
        return w[np.argmin(np.abs(w - 1j * omega))]

    assert mode(lo).real * mode(hi).real < 0
    H_ref = brentq(lambda h: mode(h).real, lo, hi, xtol=1e-13, rtol=1e-14)
    assert abs(H - H_ref) <= 1e-9 * H_ref
    assert omega == pytest.approx(mode(H_ref).imag, rel=1e-8)


@pytest.mark.slow
def test_gravity_scene_fr200_reports_the_travelling_hb():
    """The documented run (~20 min): `contin trace gravity -s Fr=200 --kx 0.006`."""
    out = subprocess.run([sys.executable, "-m", "contin", "trace", "gravity", "-s", "Fr=200", "--kx", "0.006",
                          "-q", "--json"], capture_output=True, text=True, timeout=7200)
    assert out.returncode == 0, out.stderr
    doc = json.loads(out.stdout)
    hbs = [s for s in doc["special_points"] if s["type"] == "HB" and s["data"].get("kx") == KX]
    primary = [s for s in hbs if abs(s["params"]["H"] - H_DOC) < 1e-3]
    assert len(primary) == 1
    assert abs(primary[0]["data"]["omega"] / KX - C_DOC) < 1e-3
