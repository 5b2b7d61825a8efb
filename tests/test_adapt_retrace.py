"""contin.adapt.retrace_finer: whole computations repeated on finer grids while a branch stops
under-resolved (used for gPCF fold curves, problems.couette.gravity.pitchfork_fold_curves);
checked here on a problem-free stand-in with the grid hooks only."""

from __future__ import annotations

from dataclasses import dataclass

from contin.adapt import AdaptOptions, retrace_finer, under_resolved_stop


@dataclass(frozen=True)
class Grid:
    """Stand-in problem: only the grid hooks contin.adapt.check_problem asks for."""

    grid_size: int

    def with_grid(self, n: int) -> "Grid":
        return Grid(n)

    def error_estimate(self, u, p) -> float:  # pragma: no cover - not called
        return 0.0

    def transfer(self, u, other):  # pragma: no cover - not called
        return u


@dataclass
class Stop:
    status: str
    message: str


def needs(n_needed: int, calls: list[int]):
    """A computation whose one branch stops under-resolved below n_needed intervals."""

    def compute(pb: Grid) -> list[Stop]:
        calls.append(pb.grid_size)
        if pb.grid_size < n_needed:
            return [Stop("MX", f"under-resolved at H = 40: refine the grid (try --grid {pb.grid_size + 8})")]
        return [Stop("EP", "reached bound H=70")]

    return compute


def test_growth_steps_until_resolved():
    calls: list[int] = []
    pb, branches, sizes = retrace_finer(Grid(8), needs(40, calls), AdaptOptions())
    # growth 1.5 rounded up to multiples of 4: 8, 12, 20 (18 -> 20), 32 (30 -> 32), 48
    assert sizes == calls == [8, 12, 20, 32, 48]
    assert pb.grid_size == 48 and [b.status for b in branches] == ["EP"]


def test_suggestion_skips_growth_steps():
    calls: list[int] = []
    pb, _, sizes = retrace_finer(Grid(32), needs(90, calls), AdaptOptions(), suggest=lambda p, stopped: 2 * 47)
    assert sizes == [32, 96] and pb.grid_size == 96  # 94 rounded up to a multiple of 4


def test_stops_at_max_grid_with_the_mx_branches():
    calls: list[int] = []
    pb, branches, sizes = retrace_finer(Grid(8), needs(1000, calls), AdaptOptions(max_grid=30))
    assert sizes == [8, 12, 20, 30] and pb.grid_size == 30
    assert [b.status for b in branches] == ["MX"]


def test_other_stops_are_not_retraced():
    calls: list[int] = []

    def compute(pb: Grid) -> list[Stop]:
        calls.append(pb.grid_size)
        return [Stop("MX", "no convergence in 12 iterations")]

    _, _, sizes = retrace_finer(Grid(16), compute)
    assert sizes == calls == [16]
    assert not under_resolved_stop(Stop("MX", "no convergence")) and under_resolved_stop(Stop("MX", "under-resolved at H = 1"))
    assert not under_resolved_stop(Stop("EP", "under-resolved"))


def test_no_retrace_after_a_stop_request():
    """A Ctrl-C (contin.cancel) while a computation ran: one half stopped under-resolved, the other
    by the stop.  Retracing on a finer grid would stop at its first point and replace the branch
    traced so far (qa18: the fold curve of `contin trace gravity-phase` lost that way); the
    branches are returned as they are."""
    from contin.cancel import request_stop, stop_on_sigint

    calls: list[int] = []

    def compute(pb: Grid) -> list[Stop]:
        calls.append(pb.grid_size)
        request_stop()  # the Ctrl-C came during this run
        return [Stop("MX", "backward: under-resolved at H = 40; forward: interrupted (Ctrl-C): the branch ends at "
                           "its last point")]

    with stop_on_sigint() as stop:
        pb, branches, sizes = retrace_finer(Grid(8), compute, AdaptOptions())
    assert stop.requested and sizes == calls == [8] and pb.grid_size == 8
    assert "under-resolved" in branches[0].message  # (what would have been retraced without the stop)
