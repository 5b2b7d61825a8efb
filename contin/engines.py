"""Names of the residual/Jacobian implementations a problem may offer (no imports: the CLI
builds its ``--engine`` option from them at start-up).

'auto' lets the problem pick its fastest available implementation, 'numpy' and 'numba' ask
for one (an error where it cannot run).
"""

ENGINES = ("auto", "numpy", "numba")
