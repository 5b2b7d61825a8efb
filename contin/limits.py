"""Size and step limits of user input (command line and sweep files), checked before computing.

Why: a grid of 1e9 intervals ate 330 MB/s and ignored SIGINT, ``ds = inf`` looped forever
halving an infinite step, ``--kx 0:3:1000000000`` never ended (issue 16).  The limits are far
above any useful run and are stated in ``--help``.
"""

#: largest number of grid intervals: finite-difference grids are O(N) in time and memory (fd4
#: N = 25600: 392 MiB peak for the whole pitchfork trace, issue 14), so ~1 GB here.  Dense
#: (Chebyshev) grids have their own, lower limit in the problem (``problems.discretization``).
MAX_GRID = 65536
#: largest number of continuation steps per branch
MAX_STEPS = 1_000_000
#: largest |k_x| accepted, and most wavenumbers in one list or range (``contin stability``)
MAX_ABS_KX = 1e4
MAX_KX = 10_000
#: most extra wavenumbers of ``trace --kx`` / a sweep's ``kx`` (each one is a stability pass over every branch)
MAX_TRACE_KX = 32
#: smallest --max-grid: the smallest grid adaptive resolution may choose (AdaptOptions.min_grid;
#: `--max-grid 4` ended "need 1 <= min_grid <= max_grid, got min_grid=8, max_grid=4")
MIN_MAX_GRID = 8
