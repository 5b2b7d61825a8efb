#!/usr/bin/env bash
# Regenerate every file listed in results/README.md (run from the repository root).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
for scene in bratu allen-cahn; do
    contin trace "$scene" -q -o "results/$scene.h5"
    contin diagram "results/$scene.h5" -o "results/$scene.png"
done
# codim 2 on AUTO-07p's demo ab (~20 s): its Hopf curve in (D, B) with BT and GH, the fold curve from
# that BT (with the reactor's cusp B = 16, D = e^-2), and the run as AUTO's b.ab / s.ab
contin trace ab -q -o results/ab.h5
contin continue results/ab.h5 --from HB1 --free B --bounds B=0:40 --max-steps 2000 -o results/ab_hopf.h5
contin continue results/ab_hopf.h5 --from BT2 --free B --bounds B=0:40 --max-steps 1000 -o results/ab_fold.h5
contin diagram results/ab_hopf.h5 -x D -y B -o results/ab_hopf.png
contin diagram results/ab_fold.h5 -x D -y B -o results/ab_fold.png
contin export results/ab.h5 --auto ab -d results > /dev/null
# ---- pitchfork (issue 3; ~1-2 min): nu = 0.3 default H_max; the others capped where N = 64 resolves the plug
contin trace pitchfork -s nu=0.3 -s e=0.8 -q -o results/pitchfork.h5
contin diagram results/pitchfork.h5 -o results/pitchfork.png
contin profiles results/pitchfork.h5 --at H=25 --names nu,u,T -o results/profiles_H25.png
contin profiles results/pitchfork.h5 --at H=30 --names nu,u,T -o results/profiles_H30.png
# nu:H_max -- no grid flag: the adaptive default (--tol 3e-5) refines where the plug nears
# packing (at nu = 0.5 the n = 1 plug is within 4e-7 of packing by H = 40; at nu = 0.16 the
# n = 1 plug at H = 100 is 0.02 below packing), which a fixed cheb 64 did not resolve
for spec in 0.5:40 0.16:100 0.15:100; do
    IFS=: read -r nu hmax <<< "$spec"
    contin trace pitchfork -s "nu=$nu" -s e=0.8 -s "H_max=$hmax" -q -o "results/pitchfork_nu$nu.h5"
    contin diagram "results/pitchfork_nu$nu.h5" -o "results/pitchfork_nu$nu.png"
done
# jj-walls (issue 3; ~10 s): Johnson-Jackson walls at the scene defaults
contin trace jj-walls -s nu=0.3 -s e=0.8 -q -o results/jj_walls.h5
contin diagram results/jj_walls.h5 -o results/jj_walls.png
# accuracy: key points of gPCF against method and grid (~2 min)
CONTIN_SCENES=problems.couette.keypoints:SCENES contin accuracy gpcf-keypoints \
    --grids 16,24,32,48,64,96,128,256 --tols 1e-4,1e-6,1e-8,1e-10 --repeats 3 -q -o results/accuracy
# criticality: threshold and tricritical densities at e = 0.8, and the two shipped sweeps (~3 min)
contin trace criticality -s e=0.8 --json --no-stability -q -o results/criticality_e0.8.h5 > results/criticality_e0.8.json
rm -rf results/sweeps/threshold_tricritical results/sweeps/critical_gap  # recompute, do not resume
contin sweep results/sweeps/threshold_tricritical.toml -o results/sweeps/threshold_tricritical -j 2
contin sweep results/sweeps/critical_gap.toml -o results/sweeps/critical_gap -j 2
python results/sweeps/plot_criticality.py

# ---- gravity (issue 5)
mkdir -p results/gravity
# fold curves in (H, G): the gravity-phase scene (numbers under "extra" of the JSON); the curves'
# file is only needed for the figure (augmented states, ~MBs), so it goes to a temporary file; no grid flag:
# each fold curve stopped by the resolution guard is retraced on a finer grid (cheb 32 -> 96 here)
phase_h5="$(mktemp -d)/phase_nu0.3.h5"
contin trace gravity-phase -s H_max=70 --json -q -o "$phase_h5" > results/gravity/unfold_nu0.3.json
python results/gravity/make_figures.py phase "$phase_h5"
rm -f "$phase_h5"
# normal form at the first pitchfork: branches near it at small G, then the generic fit at its label
contin trace gravity-unfolding --no-stability -q -o results/gravity/bp_unfolding.h5
contin fit results/gravity/bp_unfolding.h5 --at BP1
python results/gravity/make_figures.py all

# ---- nonlocal (issue 18; ~30 s): Dsouza-Nott non-local model, plane shear, cylinder, mu(I)
mkdir -p results/nonlocal
contin trace nonlocal-shear --no-stability --json -q -o results/nonlocal/shear.h5 > results/nonlocal/shear.json
contin trace nonlocal-cylinder --no-stability --json -q -o results/nonlocal/cylinder.h5 > results/nonlocal/cylinder.json
contin trace nonlocal-muI --no-stability --json -q -o results/nonlocal/muI.h5 > results/nonlocal/muI.json
python results/nonlocal/make_figures.py

# ---- disks (issue 17; docs/disks.md): 2-D Jenkins-Richman disks and Savage's dense closure (~30 CPU-min, most of it criticality)
mkdir -p results/disks
# adaptive (no grid flag): G_CS n = 1 ends EP at its precision limit, G_FV reaches the bound; the G_GF
# banded branches (a layer of width m_f = 0.01 where nu crosses phi_f: Chebyshev coefficients fall
# only slowly) end EP "resolution limit" on cheb 512 (n = 1 at H = 19.5, n = 2 at 37.5/36.7, n = 3 at
# 54.8; the message names the grid tol would need, ~1.2e3-7.7e3)
contin trace disks-pitchfork -q --json -o results/disks/pitchfork.h5 > results/disks/pitchfork.json
for g in cs fv gf; do
    contin diagram results/disks/pitchfork.h5 --branch $g --branch $g.n1.1 --branch $g.n1.2 --branch $g.n2.1 \
        --branch $g.n2.2 --branch $g.n3.1 --branch $g.n3.2 -o results/disks/pitchfork_$g.png
done
contin trace disks-steady -q --json -o results/disks/steady.h5 > results/disks/steady.json
contin diagram results/disks/steady.h5 -o results/disks/steady.png
contin profiles results/disks/steady.h5 --at H=128 --names nu,u,T -o results/disks/steady_profiles_H128.png
# the dense band's n = 1 branches end EP "resolution limit" on cheb 512 at H = 17.7: p_con's kink at
# phi_c (ESI Eq. 15, zero below phi_c) puts a kink into nu, whose coefficients fall like k^-2
contin trace savage-rheology -q --json -o results/disks/savage.h5 > results/disks/savage.json
contin diagram results/disks/savage.h5 --branch band --branch band.n1.1 --branch band.n1.2 -o results/disks/savage_band.png
python results/disks/make_figures.py savage results/disks/savage.json results/disks/savage.png
contin trace disks-criticality -q --json -o results/disks/criticality.h5 > results/disks/criticality.json
python results/disks/make_figures.py criticality results/disks/criticality.json results/disks/criticality.png
