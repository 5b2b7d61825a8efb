"""contin export --auto of periodic orbits: AUTO-07p's IPS = 2 layout (contin.autoorbits).

No AUTO-07p output of a periodic run is stored (its demos keep none), so the layout is checked
against AUTO's writers as they are in AUTO-07p's source (github auto-07p/auto-07p, ``src/bvp.f90``
STPLBV / WRTBV8, ``src/io.f90`` HEADNG / WRLINE), read back by a reader written here:

* b-file lines ``(I4,I6,I4,I5,nES19.10E3)``: BR (negative for periodic solutions), PT (negative:
  stable), TY, LAB, then PAR(ICP(1)), L2-NORM, MAX U(1..N2) (N2 = min(NDIM, 7 - NICP)),
  PAR(ICP(2..)); the column names in 19-character fields, ``PAR(i)``, ``L2-NORM`` and
  ``MAX U(j)`` from the field's 4th character, ``PERIOD`` (PAR(11) of IPS = 2) from its 5th.
* s-file block: the header ``(6I6,I8,I6,I8,7I5)`` IBR, MTOT, ITP, LAB, NFPR, ISW, NTPL, NAR, NROWPR,
  NTST, NCOL, NPAR, NPARI, NDIMU, IPS, IPRIV; NTPL = NTST NCOL + 1 rows ``(4X,7ES19.10E3)`` of
  T, U(1..NDIM) at TM(j) + k DTM(j) / NCOL, the last at T = 1; the ICP line ``(20I5)``; RLDOT;
  NTPL rows of UDOTPS; PAR(1..NPAR); NROWPR = (NDIM/7+1) NTPL + (NPAR+6)/7 + (NFPR+19)/20 +
  (NFPR+6)/7 + ((NDIM+6)/7) NTPL lines after the header.

The numbers are checked independently of contin's collocation: the written orbit, integrated
with scipy from u(0) for the written period, closes and passes through the written points; the
L2-NORM and MAX U columns equal AUTO's quadrature / maximum over the written rows.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.integrate import solve_ivp

from contin import io
from contin.autoformat import write_auto
from contin.cli import main

NUMBER = r" [ -]\d\.\d{10}E[+-]\d{3}"  # ES19.10E3


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture
def orbits(ab_orbits):
    return ab_orbits


def read_b(path: Path) -> tuple[list[str], list[str], list[tuple[int, int, int, int, list[float]]]]:
    """(header lines, column names, rows) by the fixed widths of AUTO's WRLINE / HEADNG."""
    lines = path.read_text().splitlines()
    header = [ln for ln in lines if ln[:4] == "   0"]
    data = [ln for ln in lines if ln[:4] != "   0"]
    ncol = (len(data[0]) - 19) // 19
    names = [header[-1][19 + 19 * i:38 + 19 * i] for i in range(ncol)]
    rows = []
    for ln in data:
        assert re.fullmatch(r"[ \d-]{4}[ \d-]{6}[ \d-]{4}[ \d-]{5}" + f"(?:{NUMBER}){{{ncol}}}", ln), ln
        rows.append((int(ln[:4]), int(ln[4:10]), int(ln[10:14]), int(ln[14:19]),
                     [float(ln[19 + 19 * i:38 + 19 * i]) for i in range(ncol)]))
    return header, names, rows


def read_s(path: Path) -> list[dict]:
    """The blocks of an s-file of periodic solutions, by WRTBV8's layout (module docstring)."""
    lines = path.read_text().splitlines()
    widths = [6] * 6 + [8, 6, 8] + [5] * 7
    out, i = [], 0
    while i < len(lines):
        head, pos = [], 0
        for w in widths:
            head.append(int(lines[i][pos:pos + w]))
            pos += w
        assert pos == len(lines[i])
        keys = "IBR MTOT ITP LAB NFPR ISW NTPL NAR NROWPR NTST NCOL NPAR NPARI NDIM IPS IPRIV".split()
        h = dict(zip(keys, head))
        body = lines[i + 1:i + 1 + h["NROWPR"]]
        assert len(body) == h["NROWPR"]
        for ln in body:
            assert re.fullmatch(f"    (?:{NUMBER}){{1,7}}", ln) or re.fullmatch(r"(?: {0,4}\d+)+", ln), ln
        ndim, ntpl = h["NDIM"], h["NTPL"]
        rows_u, rows_ud = ndim // 7 + 1, (ndim + 6) // 7

        def numbers(chunk):
            return [float(x) for ln in chunk for x in ln.split()]

        k = 0
        tu = []
        for _ in range(ntpl):
            tu.append(numbers(body[k:k + rows_u]))
            k += rows_u
        icp = [int(x) for x in body[k].split()]
        k += 1
        rldot = numbers(body[k:k + (h["NFPR"] + 6) // 7])
        k += (h["NFPR"] + 6) // 7
        ud = []
        for _ in range(ntpl):
            ud.append(numbers(body[k:k + rows_ud]))
            k += rows_ud
        par = numbers(body[k:])
        assert len(par) == h["NPAR"] and k + (h["NPAR"] + 6) // 7 == len(body)
        out.append({**h, "t": np.array(tu)[:, 0], "u": np.array(tu)[:, 1:], "icp": icp, "rldot": np.array(rldot),
                    "udot": np.array(ud), "par": par})
        i += 1 + h["NROWPR"]
    return out


def boole_l2_and_max(t: np.ndarray, u: np.ndarray) -> tuple[float, np.ndarray]:
    """AUTO's L2-NORM of the written rows of an NCOL = 4 orbit (mesh.f90 RNRMSQ with WINT's
    weights for NCOL = 4, Boole's rule (7, 32, 12, 32, 7) / 90 on each mesh interval), and the
    maxima of the components at the rows."""
    w = np.array([7, 32, 12, 32, 7]) / 90
    total = sum((t[j + 4] - t[j]) * (w @ np.sum(u[j:j + 5] ** 2, axis=1)) for j in range(0, len(t) - 1, 4))
    return math.sqrt(total), u.max(axis=0)


def ab_rhs(u: np.ndarray, d: float, b: float, beta: float) -> np.ndarray:
    """AUTO's demo ab: u1' = -u1 + D (1 - u1) e^{u2}, u2' = -u2 + D B (1 - u1) e^{u2} - beta u2."""
    h = d * (1 - u[0]) * math.exp(u[1])
    return np.array([-u[0] + h, -u[1] + b * h - beta * u[1]])


def test_b_file_of_orbits_has_autos_periodic_columns(orbits):
    header, names, rows = read_b(orbits / "b.orb")
    (br,), meta = io.load(orbits / "cyc.h5")
    assert [n.strip() for n in names] == ["PAR(1)", "L2-NORM", "MAX U(1)", "MAX U(2)", "PERIOD"]
    # HEADNG writes its names one character after the data's columns ("   0" + 16 characters): from
    # the 4th character of a field, WRITECOL(4, ...), PERIOD from the 5th
    assert [len(n) - len(n.lstrip()) for n in names] == [4, 4, 4, 4, 5]
    assert "   0   NDIM=   2   IPS =   2   IRS =   0   ILP =   1" in header
    assert "   0   NTST=  20   NCOL=   4" in header and "   0   ISW =   1   NPAR=  11" in header
    assert any(h.startswith("   0   Active continuation parameter:") and h.split()[-2:] == ["1", "11"] for h in header)
    # one row per stored orbit plus the LPC located between two of them
    lpc = br.points("LPC")[0]
    assert len(rows) == len(br) + 1 and all(r[0] == -1 for r in rows)
    assert [(r[2], r[3]) for r in rows if r[2]] == [(5, 1), (9, 2)]  # LPC1 -> LP of an ODE (5), EP2 (9)
    stored = [r for r in rows if r[2] != 5]
    np.testing.assert_array_equal([r[1] < 0 for r in stored], br.stable)  # PT < 0: stable
    np.testing.assert_allclose([r[4][0] for r in stored], br.params["D"], rtol=1e-10)
    np.testing.assert_allclose([r[4][-1] for r in stored], br.observables["period"], rtol=1e-10)
    (lpc_row,) = [r for r in rows if r[2] == 5]
    assert abs(lpc_row[4][0] - lpc.params["D"]) < 1e-10
    # the labelled orbits' L2-NORM and MAX U(j) are those of the orbits the s-file holds
    blocks = read_s(orbits / "s.orb")
    for row, block in zip([r for r in rows if r[2]], blocks):
        l2, umax = boole_l2_and_max(block["t"], block["u"])
        assert abs(row[4][1] - l2) < 1e-10 * l2
        np.testing.assert_allclose(row[4][2:4], umax, rtol=1e-10)
        assert row[4][-1] == block["par"][10] and row[4][0] == block["par"][0]


def test_s_file_blocks_are_closed_orbits_of_the_ode(orbits):
    """Each block: AUTO's header fields, the mesh times, u(1) = u(0), PAR(11) = T; the orbit
    integrated by scipy from u(0) over PAR(11) closes and passes through the written points."""
    blocks = read_s(orbits / "s.orb")
    assert [(b["ITP"], b["LAB"]) for b in blocks] == [(5, 1), (9, 2)]
    for b in blocks:
        assert (b["IBR"], b["NFPR"], b["ISW"], b["NTST"], b["NCOL"], b["NPAR"], b["NPARI"], b["NDIM"], b["IPS"],
                b["NAR"], b["NTPL"]) == (1, 2, 1, 20, 4, 11, 0, 2, 2, 3, 81)
        assert b["MTOT"] > 0 and b["icp"] == [1, 11]
        t, u = b["t"], b["u"]
        assert t.shape == (81,) and u.shape == (81, 2) and t[0] == 0.0 and t[-1] == 1.0
        assert np.all(np.diff(t) > 0)
        h = np.diff(t.reshape(-1)[:-1].reshape(20, 4), axis=1)  # NCOL equal steps inside each interval
        np.testing.assert_allclose(h, h[:, :1].repeat(3, axis=1), rtol=0, atol=2e-10)  # 11 written digits
        np.testing.assert_array_equal(u[0], u[-1])
        np.testing.assert_array_equal(b["udot"][0], b["udot"][-1])
        d, bb, beta, period = b["par"][0], b["par"][1], b["par"][2], b["par"][10]
        assert (bb, beta) == (14.0, 3.0) and 5 < period < 8
        sol = solve_ivp(lambda s, v: ab_rhs(v, d, bb, beta), (0, period), u[0], t_eval=t * period,
                        rtol=1e-11, atol=1e-12)
        scale = float(np.max(np.abs(u)))
        # the collocation error of NTST = 20, NCOL = 4 (1e-5 at LPC1, 3e-4 on the sharper orbit of EP2,
        # mostly a phase lag); the orbit closes within 1e-7 (superconvergence at the mesh points)
        assert np.max(np.abs(sol.y.T - u)) < 1e-3 * scale
        assert np.max(np.abs(sol.y[:, -1] - u[0])) < 1e-6 * scale
        # AUTO's scaling of the direction: int |udot|^2 dt + |rldot|^2 = 1
        l2, _ = boole_l2_and_max(t, b["udot"])
        assert abs(l2**2 + float(b["rldot"] @ b["rldot"]) - 1.0) < 1e-9  # 11 written digits


def test_orbit_export_refuses_par_11_and_a_file_without_its_mesh(orbits, tmp_path):
    r = run("export", orbits / "cyc.h5", "--auto", "x", "-d", tmp_path, "--par", "D=11,B=2,beta=3")
    errors = [ln for ln in r.output.splitlines() if ln.startswith("Error:")]
    assert r.exit_code == 1 and len(errors) == 1 and "PAR(11)" in errors[0], r.output
    assert not (tmp_path / "b.x").exists()
    branches, _ = io.load(orbits / "cyc.h5")
    with pytest.raises(ValueError, match="does not say their size n and NCOL"):
        write_auto(branches, "x", tmp_path)
    # the orbits' own n and NCOL: a wrong NCOL does not fit the stored rows
    with pytest.raises(ValueError, match="a stored orbit of n = 2, NTST = .*, NCOL = 3"):
        write_auto(branches, "x", tmp_path, cycles={"n": 2, "ncol": 3})


def test_type_codes_of_orbit_points(orbits, tmp_path):
    """AUTO's ODE codes (parseB.type_translation_dict): LP 5, BP 6, PD 7, TR 8, HB 3, UZ -4;
    a type AUTO has none for is written as UZ and named in the notes."""
    import dataclasses

    (br,), meta = io.load(orbits / "cyc.h5")
    lpc = br.points("LPC")[0]
    codes = {"LPC": 5, "BP": 6, "PD": 7, "NS": 8, "HB": 3, "UZ": -4, "XT": -4}
    br.special_points = [dataclasses.replace(lpc, type=t, label=k + 1) for k, t in enumerate(codes)]
    _, _, notes = write_auto([br], "t", tmp_path, cycles=meta["extra"]["cycles"])
    _, _, rows = read_b(tmp_path / "b.t")
    assert [(r[2], r[3]) for r in rows if r[2]] == [(c, k + 1) for k, c in enumerate(codes.values())]
    assert [(b["ITP"], b["LAB"]) for b in read_s(tmp_path / "s.t")] == [(c, k + 1) for k, c in enumerate(codes.values())]
    assert notes == ["XT7 (XT) written as UZ: AUTO has no code for XT of periodic orbits"]


class StuartLandauPlus:
    """Stuart-Landau (x, y) with 6 decaying components z_k' = -k z_k: n = 8, so an s-file row
    t, u_1..u_8 takes two lines and the b-file has MAX U(1..5) only.  Its orbits: the circle
    of radius sqrt(mu) in (x, y), z = 0, period 2 pi / w."""

    parameter_names = ("mu", "w")
    decay = np.arange(1.0, 7.0)

    def residual(self, u, p):
        x, y = u[:2]
        r2 = x * x + y * y
        return np.concatenate([[p["mu"] * x - p["w"] * y - x * r2, p["w"] * x + p["mu"] * y - y * r2],
                               -self.decay * u[2:]])

    def jacobian(self, u, p):
        x, y = u[:2]
        mu, w = p["mu"], p["w"]
        j = np.diag(np.concatenate([[0.0, 0.0], -self.decay]))
        j[:2, :2] = [[mu - 3 * x * x - y * y, -w - 2 * x * y], [w - 2 * x * y, mu - x * x - 3 * y * y]]
        return j

    def dresidual_dp(self, u, p, name):
        x, y = u[:2]
        return np.concatenate([[x, y] if name == "mu" else [-y, x], np.zeros(6)])


def test_eight_components_wrap_rows_and_keep_five_max_columns(tmp_path):
    """Against the closed form: L2-NORM sqrt(mu) (|u| is constant: AUTO's quadrature is exact),
    PERIOD 2 pi / w, MAX U(1), MAX U(2) within the mesh's sampling of the circle (nodes 2 pi / 80
    apart: 1 - cos(pi / 80) < 1e-3), MAX U(3..5) = 0; s-file rows of 8 components on two lines."""
    from contin.continuation import trace
    from contin.cycles import continue_cycles
    from contin.options import ContinuationOptions

    problem = StuartLandauPlus()
    steady = trace(problem, np.zeros(8), {"mu": -0.3, "w": 2.0}, "mu", ContinuationOptions(bounds={"mu": (-1, 1)}))
    (hb,) = steady.points("HB")
    br = continue_cycles(problem, hb, "mu", ContinuationOptions(bounds={"mu": (-1, 0.25)}, max_steps=40))
    assert br.status == "EP" and br.points("EP")
    write_auto([br], "sl", tmp_path, cycles={"n": 8, "ncol": 4})
    _, names, rows = read_b(tmp_path / "b.sl")
    assert [n.strip() for n in names] == ["PAR(1)", "L2-NORM"] + [f"MAX U({j})" for j in range(1, 6)] + ["PERIOD"]
    values = np.array([r[4] for r in rows])
    mu = values[:, 0]
    np.testing.assert_allclose(values[:, 1], np.sqrt(mu), rtol=1e-7)
    np.testing.assert_allclose(values[:, -1], math.pi, rtol=1e-9)
    assert np.all(values[:, 2:4] <= np.sqrt(mu)[:, None] * (1 + 1e-7))
    assert np.all(values[:, 2:4] >= np.sqrt(mu)[:, None] * (1 - 1e-3))
    assert np.all(np.abs(values[:, 4:7]) < 1e-12)
    (block,) = read_s(tmp_path / "s.sl")
    assert (block["NDIM"], block["NAR"], block["ITP"], block["par"][0], block["par"][1]) == (8, 9, 9, 0.25, 2.0)
    assert block["u"].shape == (81, 8) and block["udot"].shape == (81, 8)
    np.testing.assert_allclose(np.hypot(block["u"][:, 0], block["u"][:, 1]), 0.5, rtol=1e-7)
    assert np.all(np.abs(block["u"][:, 2:]) < 1e-12)
    lines = (tmp_path / "s.sl").read_text().splitlines()
    assert len(lines[1]) == 4 + 7 * 19 and len(lines[2]) == 4 + 2 * 19  # t, u1..u6 | u7, u8
