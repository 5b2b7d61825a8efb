"""Concrete problems for contin: demo problems (Bratu, Allen-Cahn, scalar normal forms) and
granular plane Couette flow (``problems.couette``)."""
