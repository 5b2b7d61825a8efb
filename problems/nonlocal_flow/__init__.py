"""Slow dense granular flow: the non-local constitutive model of Dsouza & Nott (2020).

Modules: :mod:`closures` (critical-state pressure Pi(phi), mu(I), the analytic plane-shear
profile), :mod:`plane` (plane shear, coupled phi-u with the mean-phi constraint),
:mod:`cylinder` (cylindrical Couette flow), :mod:`scenes` (the CLI scenes).  Equations as
implemented: docs/nonlocal.md.
"""
