"""AUTO-07p peer benchmark: the same gPCF runs on contin and on AUTO-07p (``python -m benchmarks.auto_peer``).

Files: gpcf.f90 (the model for AUTO, written from physics.md), auto.py (compile and run AUTO),
fort.py (fort.7/fort.8 readers), jobs.py (the four jobs on AUTO), contin_jobs.py (on contin),
__main__.py (paired, interleaved timing and the error table).
"""
