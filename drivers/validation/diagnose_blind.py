#!/usr/bin/env python3
"""Blind recordings for `gen4d diagnose`, made with CalculiX, and their scoring.

    diagnose_blind.py generate --out DIR --set small|full|plate|hidden-like [--seed S]
                               [--ccx ccx]
    diagnose_blind.py score --cases DIR --gen4d PATH/TO/gen4d [--np 1]
                            [--json score.json] [--only CASE ...]

Needs python3 with numpy, and `ccx` 2.20 (Debian/Ubuntu package calculix-ccx,
installed by cmake/install-deps.sh).

What `generate` makes
---------------------
Each case is a cantilever beam (box of h = 0.01 m voxels, clamped at x = 0,
gravity, a tip load pulse released at t_release = 0.3 s).  The nominal deck
`CASE/deck.toml` omits one concealed effect (or none) and has a Young's
modulus off by a factor in [0.9, 1.1].  The recording is produced by an
independent discretisation: CalculiX, quadratic hexahedra C3D20R by default
(`--element C3D8I|C3D8|C3D20R`), NLGEOM, linear elastic material (St.
Venant-Kirchhoff under NLGEOM, the deck's `stvk`).

Per case, in DIR/CASE/: `deck.toml`, `recording.csv`
(`marker,X,Y,Z,t,x,y,z`; one row per marker and sample, grouped by marker),
`truth.json`, `ccx/model.inp` (the CalculiX input; large result files are
deleted).  DIR/cases.json lists the cases.  `small` (3 cases: none, damping
alpha, heterogeneity; a 10x2x2-voxel beam, 1 s) is meant for CI and runs in
about 25 s per case (C3D20R, one core); `full` (18 cases: 4 none, 2 per
effect; 20x4x4 voxels, 2 s) takes about 8 CPU minutes per C3D20R ccx run
(5400 equations, 1000 increments, two Newton iterations each; ccx's spooles
gains nothing from a second thread here), plus the reference runs of
plasticity and material_law: about 3 hours on one core.  `plate` (4 cases:
none, damping beta, a soft region, clamp compliance; a 16x8x2-voxel plate
cantilevered from its short side, 2 s, no separability check by default) tries
diagnose on another shape than the beams it was developed on.  `hidden-like` (3
cases; a 30x5x3-voxel bar, 0.30 x 0.05 x 0.03 m, E 2e6, 1.5 s, loaded along -y, y up)
keeps the scene of two failures a hidden set of simulated recordings found:
gravity-left-out (the recording's gravity, -y, not in the deck), gravity-left-out-z
(the same along -z, across the load) and nu-off (a null case whose deck has nu 0.3
where the recording's is 0.35); 18-26 minutes of ccx a case.  `--element C3D8I`
is about 4 times faster.  `--only CASE...` generates a subset (the
parameters do not depend on the subset), so several subsets can run in
parallel into separate folders.

CalculiX model (ccx 2.20 behaviour checked by experiment)
--------------------------------------------------------
* Time integration: `*DYNAMIC, DIRECT, ALPHA=0.` with a fixed increment
  (0.002 s; automatic increments of at most that for material_law, see
  Known issues).  ccx accepts ALPHA in [-1/3, 0] (larger values are reset to 0,
  smaller to -1/3 with a warning); 0 is the Newmark trapezoidal rule, no
  numerical dissipation.
* Tip load: `*CLOAD` on the nodes of the x = L face, one `*AMPLITUDE`
  (TIME=TOTAL TIME) per loaded dof (ccx allows one amplitude per node and
  dof) that is the sum of the deck's [[force]] pulses: constant on
  [start, end), with jumps over 2e-6 s centred on the switching time.  ccx
  evaluates loads at increment ends, so a jump acts as a step change that
  takes the mean of its one-sided values at the switching time itself (the
  lateral pulse is released at t_release = 0.3 s): the trapezoidal rule then
  delivers the pulse's exact impulse.  The total force equals the deck's; it is shared over
  the face nodes by their tributary face area (below), which for the voxel
  model is also its nodal-mass share.
* Tributary areas of the nodes of a boundary face of area h^2: C3D8/C3D8I:
  h^2/4 per corner.  C3D20R: the consistent load of a uniform traction gives
  corners -1/12 and midsides 1/3, i.e. negative corners; instead we lump
  with the HRZ row scaling of the quadratic face (corners 1/36, midsides 2/9
  of the face area: positive, sums to the face area).  These areas are used
  for the tip load, the clamp dashpots and the air-drag dashpots.
* Gravity: `*DLOAD, EALL, GRAV, |g|, direction`.
* Output: `*NODE PRINT` of U for the marker nodes and a tip probe every
  increment, parsed from the .dat file; the displacements are interpolated
  to the jittered sample times with Catmull-Rom cubics over the increments.

Effects (names and parameters as `gen4d diagnose` reports them)
---------------------------------------------------------------
* none: only E is off.
* damping: Rayleigh C = alpha M + beta K, `*DAMPING, ALPHA=.., BETA=..` in
  the model definition (one global card; verified: the amplitude decays).
  One case mass-proportional (alpha, 1/s), one stiffness-proportional (beta,
  s).
* plasticity: von Mises with linear isotropic hardening, `*PLASTIC` with the
  points (yield_stress, 0) and (yield_stress + hardening, 1).  An elastic
  reference run (to t = 0.6 s) gives the peak von Mises stress at the
  integration points of the second element layer from the clamp (the first
  layer's corner stresses are dominated by the clamp singularity: calibrated
  on them the permanent set of the full beam was only 0.07 mm);
  yield_stress is 60-70 % of it.
* heterogeneity: a voxel-aligned box of elements with E times
  stiffness_factor (region in truth.json, reference coordinates).
* gravity: the deck has gravity 0 while the data has -9.81 z, or the deck has
  -z while the data's gravity is tilted about x (parameters gx, gy, gz).
* clamp_compliance: the x = 0 nodes are not fixed; the face rests on a
  continuous elastic foundation of `stiffness` [N/m per m^2] in x, y and z,
  with the foundation's consistent stiffness k int N_i N_j dA over each face
  of the elements (as gen4d integrates its own): SPRING2 elements of
  -K_ij between the face's nodes and SPRING1 elements of the row sums
  to ground, per direction (the C3D20R corners' row sums are negative, the
  whole matrix positive definite; ccx accepts both).  Lumped springs
  (stiffness * tributary area, used until this was found) give a two-element
  thick face 1.17 times the foundation's rotational stiffness, 1.25 times in
  a static ccx test of the plate's root, and gen4d had to fit that.  Each
  node also has a DASHPOTA element to a fixed ground node 1 km away along
  each axis (damping * tributary area): ccx has no per-direction two-node
  dashpot to make the damping consistent too, so the damping, which is not
  scored, keeps the lumped weights.
  Stiffness is picked for a 15-22 % lower first frequency.
* air_drag: linear only (`quadratic` = 0): three DASHPOTA per surface node
  (x, y, z, to fixed ground nodes 1 km away, so that each keeps its axis as the
  node moves) with coefficient linear * A_i,
  A_i the node's exposed tributary area.
* material_law: the data uses `*HYPERELASTIC, NEO HOOKE`, ccx's energy
  U = C10 (I1bar - 3) + (J - 1)^2 / D1 with C10 = mu/2, D1 = 2/K
  (mu = E / (2 (1 + nu)), K = E / (3 (1 - 2 nu))); the deck says stvk.  To
  make the laws differ a large axial pull (6-10 % strain) is added to the
  tip load, switched on and off in 10 stairs of 0.01 s (extra [[force]]
  tables in the deck; a single step of that size inverts the tip elements
  in ccx's first increment).  A St. Venant-Kirchhoff reference run gives the marker RMS
  difference; below 3 noise sigmas the case is marked `"detectable": false`
  and scored as correct when the report says the effect, none or ambiguous.
* Not generated (ccx cannot produce them in this setting): viscoelasticity,
  coulomb_damping, contact_friction, quadratic air drag.

Known issues (ccx 2.20, fixed increments of 0.002 s)
----------------------------------------------------
* material_law on the full beam: with fixed increments (`DIRECT`) ccx
  stopped with "solution seems to diverge" in the first increment of the
  axial pull, for any first stair of 0.6 % strain or more (the stair count
  did not matter; 0.06 % ran).  The material_law cases (truth and StVK
  reference) therefore use automatic increments (at most dt, cut back where
  Newton fails) with the output at `*TIME POINTS` on the dt grid, so the
  samples stay on a uniform grid; every other case keeps `DIRECT` (their
  inputs are unchanged byte for byte).
* `--element C3D8I` diverged on the full beam (heterogeneity-soft,
  clamp-1) while C3D20R ran; C3D8 and C3D8I are not validated.
* plasticity: with yield at 60-70 % of the peak stress the permanent set is
  small (full beam, clamp-layer calibration: 0.07 mm, a 5.7 sigma marker
  difference); the second-layer calibration raises it (small beam: 1.6 ->
  2.3 mm) but the full beam was not rerun.

Separability (`--separability`, on by default for the full set): on a
uniform cantilever, mass-proportional damping (alpha M) and linear drag on
the surface damp every bending mode alike once alpha = c (P L + 4 A_tip) /
(rho A L).  For damping (alpha only) and air_drag cases the generator fits
the other effect's coefficient to the noise-free markers with CalculiX (the
modal equivalent, a 25 % larger value and one Gauss-Newton step: 3 more runs)
and records the best chi-square difference, delta_chi2, an upper bound (E
and the rest held at the truth).  Two models whose predictions differ by d
(in noise sigmas) give a likelihood ratio of mean |d|^2 and sd 2|d|: a
Vuong-type z of sqrt(delta_chi2) / 2.  Below delta_chi2 = 15.4 (z 1.96) the
case is marked inseparable, and `score` counts an "ambiguous" verdict whose
two contenders are the truth and that confounder as correct; it prints how
many were counted so, beside the cases where the effect was named alone.

truth.json: effect, parameters, scored_parameters (checked within 20 %),
region, E_true, E_nominal, noise_sigma, element, notes, detectable,
detect_snr (marker RMS difference to the effect-free reference / sigma,
where a reference was run), separability (confounder, its fitted value and
modal estimate, delta_chi2, separable; null where not checked).

`score` runs `gen4d diagnose` on every case (`mpirun -np N` for N > 1, with
the OpenMPI settings of jobs/env.sh), reads CASE/diag/report.json and prints
a confusion matrix, the fraction of correct effects (target >= 90 %), false
discoveries on null cases (target 0), held-out RMS reduction per effect case
(target >= 50 %), relative errors of the scored parameters (target <= 20 %),
the heterogeneity region IoU (target >= 0.5) and the wall time per case.
Exit code 0 when all targets are met, 1 otherwise, 2 on usage errors.
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

T_RELEASE = 0.3
GROUND_DISTANCE = 1000.0  # m, dashpots' ground nodes (see Grounds.dashpots)
STAIRS, STAIR = 10, 0.01   # material_law: axial pull switched on/off in stairs
SEPARABLE_CHI2 = 4 * 1.96 ** 2  # confounder check: Vuong-type z = sqrt(delta_chi2) / 2
FS = 100.0
RHO = 1000.0
NU = 0.3
G = 9.81


# ----------------------------------------------------------------------------
# Case specifications


def beam(kind):
    """Geometry, loads and material of the small and the full beam."""
    if kind == "small":
        return dict(n=(10, 2, 2), h=0.01, E=3.0e5, end_time=1.0, dt=0.002,
                    force=(0.0, 0.10, -0.08), markers=6)
    if kind == "plate":
        # a cantilevered plate, 16 x 8 x 2 voxels: the softest bending is out of plane, the
        # in-plane one 16x stiffer, and the first torsion mode lies between them
        return dict(n=(16, 8, 2), h=0.01, E=1.0e6, end_time=2.0, dt=0.002,
                    force=(0.0, 3.0, -0.5), markers=10)
    if kind == "hidden":
        # a 0.30 x 0.05 x 0.03 m bar, three voxels through its thickness (z), pushed along -y
        # (the 0.05 m side) by its tip load and, y being up, pulled along -y by gravity
        return dict(n=(30, 5, 3), h=0.01, E=2.0e6, end_time=1.5, dt=0.002,
                    force=(0.0, -1.0, 0.0), markers=10, gravity=(0.0, -G, 0.0))
    return dict(n=(20, 4, 4), h=0.01, E=5.0e5, end_time=2.0, dt=0.002,
                force=(0.0, 0.6, -0.4), markers=10)


def base_case(name, kind, rng, effect=None, params=None, scored=(), noise=None):
    b = beam(kind)
    sign = rng.choice([-1.0, 1.0])
    if kind == "hidden":  # the load's direction is part of the scene: no random sign
        sign = 1.0
    f = np.array(b["force"]) * rng.uniform(0.8, 1.2) * np.array([1.0, sign, 1.0])
    g = list(b.get("gravity", (0.0, 0.0, -G)))
    return dict(name=name, kind=kind, n=b["n"], h=b["h"], end_time=b["end_time"],
                dt=b["dt"], E_true=b["E"], E_factor=float(rng.uniform(0.9, 1.1)),
                nu_true=NU, nu_deck=NU,
                force=[float(v) for v in f], g_true=list(g), g_deck=list(g),
                noise=noise if noise is not None else (
                    1e-4 if kind == "small" else float(rng.uniform(5e-5, 2e-4))),
                markers=b["markers"], seed=int(rng.integers(1 << 31)), effect=effect,
                params=dict(params or {}), scored=list(scored), region=None,
                notes="", pulses=[])


def length(case):
    return case["n"][0] * case["h"]


def case_heterogeneity(name, kind, rng, factor):
    c = base_case(name, kind, rng, "heterogeneity", {"stiffness_factor": factor},
                  ["stiffness_factor"])
    nx, ny, nz = c["n"]
    wx = 3 if kind == "small" else 4
    i0 = int(rng.integers(0, nx // 2 - wx + 2))
    h = c["h"]
    c["region"] = [[i0 * h, 0.0, 0.0], [(i0 + wx) * h, ny * h, nz * h]]
    c["notes"] = "E times %.3g in voxels x index %d..%d (full cross-section)" % (
        factor, i0, i0 + wx - 1)
    return c


def case_clamp(name, rng, drop, kind="full"):
    c = base_case(name, kind, rng, "clamp_compliance")
    r = 1.0 / (1.0 - drop) ** 2 - 1.0          # extra tip compliance ratio
    k = 3.0 * c["E_true"] / (length(c) * r)   # rotational-spring estimate
    c["params"] = {"stiffness": float(k),
                   "damping": float(k * rng.uniform(5e-4, 1.5e-3))}
    c["scored"] = ["stiffness"]
    c["notes"] = "stiffness aimed at a %.0f %% lower first frequency" % (100 * drop)
    return c


def case_gravity(name, rng, tilted):
    c = base_case(name, "full", rng, "gravity")
    if tilted:
        a = math.radians(rng.uniform(10.0, 20.0))
        c["g_true"] = [0.0, -G * math.sin(a), -G * math.cos(a)]
        c["scored"] = ["gy", "gz"]
        c["notes"] = "deck gravity -z, data tilted %.1f deg about x" % math.degrees(a)
    else:
        c["g_deck"] = [0.0, 0.0, 0.0]
        c["scored"] = ["gz"]
        c["notes"] = "deck has no gravity"
    c["params"] = dict(zip(("gx", "gy", "gz"), c["g_true"]))
    return c


def case_material_law(name, rng, strain):
    c = base_case(name, "full", rng, "material_law", {"law": "neo_hookean"})
    nx, ny, nz = c["n"]
    area = ny * nz * c["h"] ** 2
    fx = strain * c["E_true"] * area
    c["pulses"] = [(k * STAIR, T_RELEASE + k * STAIR, [fx / STAIRS, 0.0, 0.0])
                   for k in range(STAIRS)]
    c["notes"] = ("axial pull of %.4g N (%.0f %% strain) added to the tip load in %d stairs of "
                  "%g s up from t = 0 and down from t = %g s" % (fx, 100 * strain, STAIRS,
                                                               STAIR, T_RELEASE))
    return c


def cases_small(rng):
    return [base_case("none-1", "small", rng),
            base_case("damping-alpha", "small", rng, "damping",
                      {"alpha": float(rng.uniform(1.0, 2.0)), "beta": 0.0}, ["alpha"]),
            case_heterogeneity("heterogeneity-1", "small", rng, float(rng.uniform(0.3, 0.5)))]


def cases_full(rng):
    cs = [base_case("none-%d" % i, "full", rng) for i in (1, 2, 3, 4)]
    cs.append(base_case("damping-alpha", "full", rng, "damping",
                        {"alpha": float(rng.uniform(0.5, 2.0)), "beta": 0.0}, ["alpha"]))
    cs.append(base_case("damping-beta", "full", rng, "damping",
                        {"alpha": 0.0, "beta": float(rng.uniform(1e-3, 5e-3))}, ["beta"]))
    for i in (1, 2):
        c = base_case("plasticity-%d" % i, "full", rng, "plasticity", {}, ["yield_stress"])
        c["yield_fraction"] = float(rng.uniform(0.6, 0.7))
        c["hardening_fraction"] = float(rng.uniform(0.05, 0.2))
        cs.append(c)
    cs.append(case_heterogeneity("heterogeneity-soft", "full", rng, float(rng.uniform(0.3, 0.5))))
    cs.append(case_heterogeneity("heterogeneity-stiff", "full", rng, float(rng.uniform(2.0, 3.0))))
    cs.append(case_gravity("gravity-missing", rng, False))
    cs.append(case_gravity("gravity-tilted", rng, True))
    cs.append(case_clamp("clamp-1", rng, 0.15))
    cs.append(case_clamp("clamp-2", rng, 0.22))
    for i, lin in ((1, rng.uniform(5.0, 9.0)), (2, rng.uniform(10.0, 15.0))):
        cs.append(base_case("air-drag-%d" % i, "full", rng, "air_drag",
                            {"linear": float(lin), "quadratic": 0.0}, ["linear"]))
    cs.append(case_material_law("material-law-1", rng, 0.06))
    cs.append(case_material_law("material-law-2", rng, 0.10))
    return cs


def cases_hidden(rng):
    """The two failures a hidden set of simulated recordings found, on its scene: a
    0.30 x 0.05 x 0.03 m bar (three voxels thick) loaded along -y, starting straight and
    unstressed with gravity switched on at t = 0.  gravity-left-out: the recording has
    gravity (-y, along the load), the deck has none; gravity-left-out-z: the same with the
    recording's gravity along -z, across the load.  nu-off: a null case whose deck has
    Poisson's ratio 0.3 where the recording's is 0.35 (and E off as in every case)."""
    g = base_case("gravity-left-out", "hidden", rng, "gravity")
    g["g_deck"] = [0.0, 0.0, 0.0]
    g["params"] = dict(zip(("gx", "gy", "gz"), g["g_true"]))
    g["scored"] = ["gy"]
    g["notes"] = "deck has no gravity; the bar starts straight with gravity on from t = 0"
    n = base_case("nu-off", "hidden", rng)
    n["nu_true"] = 0.35
    n["notes"] = "null case: the deck's Poisson's ratio is 0.3, the recording's 0.35"
    z = base_case("gravity-left-out-z", "hidden", rng, "gravity")
    z["g_true"], z["g_deck"] = [0.0, 0.0, -G], [0.0, 0.0, 0.0]
    z["params"] = dict(zip(("gx", "gy", "gz"), z["g_true"]))
    z["scored"] = ["gz"]
    z["notes"] = ("deck has no gravity; the recording's pulls along -z, across the load, "
                  "bending the bar through its 0.03 m thickness")
    return [g, n, z]


def cases_plate(rng):
    """Another geometry than the beams the rest of diagnose was developed on."""
    return [base_case("none-1", "plate", rng),
            base_case("damping-beta", "plate", rng, "damping",
                      {"alpha": 0.0, "beta": float(rng.uniform(1e-3, 5e-3))}, ["beta"]),
            case_heterogeneity("heterogeneity-soft", "plate", rng, float(rng.uniform(0.3, 0.5))),
            case_clamp("clamp-1", rng, 0.15, "plate")]


# ----------------------------------------------------------------------------
# Mesh


def face_shapes(quadratic, x, y):
    """Shape functions of a quadrilateral face on [-1, 1]^2: corners (-1,-1), (1,-1),
    (1,1), (-1,1), then (quadratic, serendipity) the midsides of those edges in order."""
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    if not quadratic:
        return np.array([0.25 * (1 + a * x) * (1 + b * y) for a, b in corners])
    out = [0.25 * (1 + a * x) * (1 + b * y) * (a * x + b * y - 1) for a, b in corners]
    for a, b in [(0, -1), (1, 0), (0, 1), (-1, 0)]:
        out.append(0.5 * (1 - x * x) * (1 + b * y) if a == 0 else 0.5 * (1 + a * x) * (1 - y * y))
    return np.array(out)


def face_mass_matrix(quadratic):
    """int N_i N_j dA over a unit-area face (3-point Gauss per axis, exact for these
    degrees); its rows sum to the consistent load shares (-1/12 corners, 1/3 midsides
    for the serendipity face)."""
    g, w = np.polynomial.legendre.leggauss(3)
    n = 8 if quadratic else 4
    M = np.zeros((n, n))
    for i in range(3):
        for j in range(3):
            N = face_shapes(quadratic, g[i], g[j])
            M += w[i] * w[j] * np.outer(N, N)
    return M / 4.0


class Mesh:
    """Structured hexahedral mesh of the box on a half-spacing index grid."""

    CORNERS = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0),
               (0, 0, 2), (2, 0, 2), (2, 2, 2), (0, 2, 2)]
    EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
             (0, 4), (1, 5), (2, 6), (3, 7)]

    def __init__(self, n, h, element):
        self.n, self.h, self.element = n, h, element
        self.quadratic = element == "C3D20R"
        nx, ny, nz = n
        self.nodes = {}
        for k in range(2 * nz + 1):
            for j in range(2 * ny + 1):
                for i in range(2 * nx + 1):
                    odd = i % 2 + j % 2 + k % 2
                    if odd == 0 or (self.quadratic and odd == 1):
                        self.nodes[self.nid(i, j, k)] = (i, j, k)
        self.elements = [self.element_nodes(i, j, k) for k in range(nz)
                         for j in range(ny) for i in range(nx)]
        self.element_index = [(i, j, k) for k in range(nz) for j in range(ny) for i in range(nx)]

    def nid(self, i, j, k):
        nx, ny, _ = self.n
        return 1 + i + (2 * nx + 1) * (j + (2 * ny + 1) * k)

    def xyz(self, node):
        return tuple(0.5 * self.h * v for v in self.nodes[node])

    def element_nodes(self, i, j, k):
        c = [(2 * i + a, 2 * j + b, 2 * k + d) for a, b, d in self.CORNERS]
        ids = [self.nid(*p) for p in c]
        if self.quadratic:
            for a, b in self.EDGES:
                ids.append(self.nid(*[(c[a][d] + c[b][d]) // 2 for d in range(3)]))
        return ids

    def boundary_faces(self):
        """Yield (axis, side, node ids of the face's grid points) of every
        element face on the box surface."""
        nx, ny, nz = self.n
        counts = (nx, ny, nz)
        for axis in range(3):
            a1, a2 = [d for d in range(3) if d != axis]
            for side in (0, 1):
                fixed = 2 * counts[axis] * side
                for p in range(counts[a1]):
                    for q in range(counts[a2]):
                        pts = []
                        for u in range(3):
                            for v in range(3):
                                idx = [0, 0, 0]
                                idx[axis], idx[a1], idx[a2] = fixed, 2 * p + u, 2 * q + v
                                pts.append(tuple(idx))
                        yield axis, side, pts

    def face_weights(self, pts):
        """Tributary fractions of a face's nodes (see the docstring)."""
        out = {}
        for idx in pts:
            odd = sum(v % 2 for v in idx)
            nid = self.nid(*idx)
            if nid not in self.nodes:
                continue
            if not self.quadratic:
                if odd == 0:
                    out[nid] = 0.25
            elif odd == 0:
                out[nid] = 1.0 / 36.0
            elif odd == 1:
                out[nid] = 2.0 / 9.0
        return out

    def face_foundation(self, pts):
        """Node ids of one element face and its consistent matrix int N_i N_j dA
        (serendipity 8-node face for C3D20R, bilinear for C3D8/C3D8I)."""
        order = [(0, 0), (2, 0), (2, 2), (0, 2)]
        if self.quadratic:
            order += [(1, 0), (2, 1), (1, 2), (0, 1)]
        ids = [self.nid(*pts[3 * a + b]) for a, b in order]
        return ids, face_mass_matrix(self.quadratic) * self.h ** 2

    def areas(self, select):
        """Tributary area per node of the boundary faces with select(axis, side)."""
        area = {}
        for axis, side, pts in self.boundary_faces():
            if not select(axis, side):
                continue
            for nid, w in self.face_weights(pts).items():
                area[nid] = area.get(nid, 0.0) + w * self.h ** 2
        return area

    def surface_grid_nodes(self):
        """Voxel-grid (corner) nodes on the surface, not on the clamped face."""
        nx, ny, nz = self.n
        out = []
        for nid, (i, j, k) in self.nodes.items():
            if i % 2 or j % 2 or k % 2 or i == 0:
                continue
            if j in (0, 2 * ny) or k in (0, 2 * nz) or i == 2 * nx:
                out.append(nid)
        return sorted(out)


# ----------------------------------------------------------------------------
# CalculiX input


def fmt(v):
    return "%.9e" % v


def lines_mesh(mesh):
    out = ["*NODE"]
    for nid in sorted(mesh.nodes):
        out.append("%d,%s,%s,%s" % ((nid,) + tuple(fmt(v) for v in mesh.xyz(nid))))
    out.append("*ELEMENT,TYPE=%s,ELSET=EALL" % mesh.element)
    for e, ids in enumerate(mesh.elements):
        s = [str(e + 1)] + [str(v) for v in ids]
        out.append(",".join(s[:16]))
        if len(s) > 16:
            out.append(",".join(s[16:]))
    return out


def nset(name, ids):
    ids = sorted(ids)
    out = ["*NSET,NSET=%s" % name]
    for i in range(0, len(ids), 12):
        out.append(",".join(str(v) for v in ids[i:i + 12]))
    return out


def elset(name, ids):
    return ["*ELSET,ELSET=%s" % name] + [",".join(str(v) for v in ids[i:i + 12])
                                         for i in range(0, len(ids), 12)]


def lines_material(name, E, law, plastic, nu=NU):
    out = ["*MATERIAL,NAME=%s" % name]
    if law == "neo_hookean":
        mu, K = E / (2 * (1 + nu)), E / (3 * (1 - 2 * nu))
        out += ["*HYPERELASTIC,NEO HOOKE", "%s,%s" % (fmt(mu / 2), fmt(2 / K))]
    else:
        out += ["*ELASTIC", "%s,%s" % (fmt(E), fmt(nu))]
    if plastic:
        sy, H = plastic
        out += ["*PLASTIC", "%s,0.0" % fmt(sy), "%s,1.0" % fmt(sy + H)]
    return out + ["*DENSITY", fmt(RHO)]


def force_at(pulses, dof, t):
    return sum(f[dof] for t0, t1, f in pulses if t0 <= t < t1)


def peak_force(pulses, dof):
    return max(abs(force_at(pulses, dof, t0)) for t0, _, _ in pulses)


def lines_amplitude(name, pulses, dof, scale, end_time):
    """Amplitude of the total tip force in one dof, the sum of the pulses
    (force on [start, end)) over scale.  ccx allows one amplitude per loaded
    dof.  Loads are evaluated at increment ends; a jump at an increment end
    takes the mean of its one-sided values there (ramps of 1e-6 s on either
    side), so that the trapezoidal rule delivers the pulse's exact impulse,
    as gen4d's model does.  Holding the full force at the end time (the
    first version) added half an increment of impulse: a 5 % larger free
    swing in y on the full beam."""
    def value(t):
        return force_at(pulses, dof, t) / scale

    breaks = sorted({t for t0, t1, _ in pulses for t in (t0, t1) if t > 0.0})
    pts = [(0.0, value(0.0))]
    for t in breaks:
        before, after = value(t - 1e-9), value(t)
        pts += [(t - 1e-6, before), (t, 0.5 * (before + after)), (t + 1e-6, after)]
    pts.append((end_time + 10.0, value(end_time + 10.0)))
    return (["*AMPLITUDE,NAME=%s,TIME=TOTAL TIME" % name]
            + [",".join("%s,%s" % (fmt(t), fmt(v)) for t, v in pts[i:i + 4])
               for i in range(0, len(pts), 4)])


class Grounds:
    """Fixed ground nodes and one-node springs / two-node dashpots to them."""

    def __init__(self, mesh):
        self.mesh = mesh
        self.next_node = max(mesh.nodes) + 1
        self.next_elem = len(mesh.elements) + 1
        self.nodes, self.lines, self.ground = [], [], []
        self.sets = 0

    def dashpots(self, node_coef):
        """Dashpots in x, y and z from each node to a ground node GROUND_DISTANCE away.

        A DASHPOTA acts along the line between its nodes, which turns as the node moves:
        at 1 m away a lateral swing of u tilts it by u / 1 m (3-5 % on the full beam), so
        the x, y and z dashpots of a node couple its directions and the drag is no longer
        the isotropic linear law the truth names.  On the small damping-alpha case that
        artifact alone made mass damping and surface drag look separable (CalculiX fit of
        the drag to the noise-free markers: chi-square 40.8 with grounds 1 m away, 2.4 at
        100 m; gen4d's voxels: 0.75 at h, 1.6 at h/4)."""
        groups = group_by_value(node_coef)
        for coef, nodes in groups:
            self.sets += 1
            name = "DP%d" % self.sets
            self.lines.append("*ELEMENT,TYPE=DASHPOTA,ELSET=%s" % name)
            for nid in nodes:
                x = self.mesh.xyz(nid)
                for d in range(3):
                    g = list(x)
                    g[d] -= GROUND_DISTANCE
                    self.nodes.append((self.next_node, g))
                    self.ground.append(self.next_node)
                    self.lines.append("%d,%d,%d" % (self.next_elem, nid, self.next_node))
                    self.next_node += 1
                    self.next_elem += 1
            self.lines += ["*DASHPOT,ELSET=%s" % name, "", fmt(coef)]

    def springs(self, node_coef):
        """SPRING1 elements in x, y and z at each node."""
        for coef, nodes in group_by_value(node_coef):
            for d in range(3):
                self.sets += 1
                name = "SP%d" % self.sets
                self.lines.append("*ELEMENT,TYPE=SPRING1,ELSET=%s" % name)
                for nid in nodes:
                    self.lines.append("%d,%d" % (self.next_elem, nid))
                    self.next_elem += 1
                self.lines += ["*SPRING,ELSET=%s" % name, str(d + 1), fmt(coef)]

    def foundation(self, mesh, select, k):
        """A continuous elastic foundation of k [N/m per m^2] in x, y and z under the
        boundary faces with select(axis, side), with its consistent stiffness: SPRING2
        elements of -K_ij between the nodes of each face and SPRING1 elements of the row
        sums to ground (see clamp_compliance in the module docstring)."""
        K = {}
        for axis, side, pts in mesh.boundary_faces():
            if not select(axis, side):
                continue
            ids, M = mesh.face_foundation(pts)
            for a, ia in enumerate(ids):
                for b, ib in enumerate(ids):
                    K[(ia, ib)] = K.get((ia, ib), 0.0) + k * M[a, b]
        rows = {}
        for (a, _), v in K.items():
            rows[a] = rows.get(a, 0.0) + v
        self.springs(rows)
        pairs = {}
        for (a, b), v in K.items():
            if a < b and v != 0.0:
                pairs.setdefault(round(-v, 12), []).append((a, b))
        for coef, ab in sorted(pairs.items()):
            for d in range(3):
                self.sets += 1
                name = "SP%d" % self.sets
                self.lines.append("*ELEMENT,TYPE=SPRING2,ELSET=%s" % name)
                for a, b in ab:
                    self.lines.append("%d,%d,%d" % (self.next_elem, a, b))
                    self.next_elem += 1
                self.lines += ["*SPRING,ELSET=%s" % name, "%d,%d" % (d + 1, d + 1), fmt(coef)]

    def output(self):
        if not self.nodes:
            return []
        out = ["*NODE"] + ["%d,%s,%s,%s" % ((n,) + tuple(fmt(v) for v in g))
                           for n, g in self.nodes]
        return out + self.lines + nset("NGROUND", self.ground) + ["*BOUNDARY", "NGROUND,1,3"]


def group_by_value(node_coef):
    groups = {}
    for nid, c in node_coef.items():
        groups.setdefault(round(c, 12), []).append(nid)
    return sorted(groups.items())


def write_inp(case, mesh, variant, print_nodes, end_time, clamp_stress=False):
    """The ccx input of a case.  variant: 'truth' or 'reference' (effect off,
    except that 'reference' keeps the truth's gravity and loads)."""
    eff = case["effect"] if variant == "truth" else None
    p = case["params"]
    E = case["E_true"]
    out = ["*HEADING", "gen4d diagnose blind case %s (%s)" % (case["name"], variant)]
    out += lines_mesh(mesh)
    h, (nx, ny, nz) = mesh.h, mesh.n
    clamp = [nid for nid, (i, _, _) in mesh.nodes.items() if i == 0]
    tip_area = mesh.areas(lambda axis, side: axis == 0 and side == 1)
    out += nset("NCLAMP", clamp) + nset("NPRINT", print_nodes)
    ehet = []
    if eff == "heterogeneity":
        (x0, _, _), (x1, _, _) = case["region"]
        ehet = [e + 1 for e, (i, j, k) in enumerate(mesh.element_index)
                if x0 - 1e-9 < i * h and (i + 1) * h < x1 + 1e-9]
    ebase = [e + 1 for e in range(len(mesh.elements)) if e + 1 not in set(ehet)]
    out += elset("EBASE", ebase)
    out += elset("ESTRESS", [e + 1 for e, (i, _, _) in enumerate(mesh.element_index) if i == 1])
    plastic = None
    if eff == "plasticity":
        plastic = (p["yield_stress"], p["hardening"])
    law = "neo_hookean" if eff == "material_law" else "stvk"
    nu = case.get("nu_true", NU)
    out += lines_material("MBASE", E, law, plastic, nu)
    out += ["*SOLID SECTION,ELSET=EBASE,MATERIAL=MBASE"]
    if ehet:
        out += elset("EHET", ehet) + lines_material("MHET", E * p["stiffness_factor"], law, None,
                                                     nu)
        out += ["*SOLID SECTION,ELSET=EHET,MATERIAL=MHET"]
    grounds = Grounds(mesh)
    if eff == "clamp_compliance":
        area = mesh.areas(lambda axis, side: axis == 0 and side == 0)
        grounds.foundation(mesh, lambda axis, side: axis == 0 and side == 0, p["stiffness"])
        grounds.dashpots({n: p["damping"] * a for n, a in area.items()})
    else:
        out += ["*BOUNDARY", "NCLAMP,1,3"]
    if eff == "air_drag":
        area = mesh.areas(lambda axis, side: not (axis == 0 and side == 0))
        grounds.dashpots({n: p["linear"] * a for n, a in area.items()})
    out += grounds.output()
    if eff == "damping":
        out += ["*DAMPING,ALPHA=%s,BETA=%s" % (fmt(p["alpha"]), fmt(p["beta"]))]
    pulses = [(0.0, T_RELEASE, case["force"])] + list(case["pulses"])
    scale = [peak_force(pulses, d) for d in range(3)]
    for d in range(3):
        if scale[d] > 0.0:
            out += lines_amplitude("LOAD%d" % (d + 1), pulses, d, scale[d], end_time)
    g = case["g_true"]
    gm = math.sqrt(sum(v * v for v in g))
    # material_law: fixed increments diverge in the first one under the axial pull (NEO HOOKE,
    # full beam, any stair of 0.6 % strain or more); automatic increments (at most dt, cut
    # back where Newton fails) with the output at TIME POINTS keep the dt grid of samples.
    # The plate needs them too: with fixed increments Newton diverges in its first swing.
    dt = case["dt"]
    auto = case["effect"] == "material_law" or case["kind"] == "plate"
    if auto:
        n = int(round(end_time / dt))
        out += ["*TIME POINTS,NAME=TP,TIME=TOTAL TIME"]
        out += [",".join(fmt(dt * k) for k in range(i, min(i + 8, n + 1)))
                for i in range(1, n + 1, 8)]
    out += ["*STEP,NLGEOM,INC=1000000"]
    out += (["*DYNAMIC,ALPHA=0.", "%s,%s,%s,%s" % (fmt(dt), fmt(end_time), fmt(1e-7), fmt(dt))]
            if auto else ["*DYNAMIC,DIRECT,ALPHA=0.", "%s,%s" % (fmt(dt), fmt(end_time))])
    if gm > 0:
        out += ["*DLOAD", "EALL,GRAV,%s,%s,%s,%s" % ((fmt(gm),) + tuple(fmt(v / gm) for v in g))]
    total = sum(tip_area.values())
    for d in range(3):
        if scale[d] > 0.0:
            out += ["*CLOAD,AMPLITUDE=LOAD%d" % (d + 1)]
            out += ["%d,%d,%s" % (nid, d + 1, fmt(scale[d] * tip_area[nid] / total))
                    for nid in sorted(tip_area)]
    out += ["*NODE PRINT,NSET=NPRINT,%s" % ("TIME POINTS=TP" if auto else "FREQUENCY=1"), "U"]
    if clamp_stress:
        out += ["*EL PRINT,ELSET=ESTRESS,FREQUENCY=2", "S"]
    out += ["*END STEP"]
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------
# Running ccx and reading its output


class CcxError(RuntimeError):
    pass


def find_ccx(name):
    path = shutil.which(name)
    if not path:
        sys.stderr.write("ccx not found; install calculix-ccx (cmake/install-deps.sh)\n")
        sys.exit(2)
    return path


def run_ccx(ccx, inp, label, keep_dir=None):
    """Run ccx on the input text; return (times, {node: u[T,3]}, stresses)."""
    tmp = tempfile.mkdtemp(prefix="ccx-")
    try:
        with open(os.path.join(tmp, "model.inp"), "w") as f:
            f.write(inp)
        env = dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1"))
        proc = subprocess.run([ccx, "-i", "model"], cwd=tmp, env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        log = proc.stdout
        dat = os.path.join(tmp, "model.dat")
        bad = proc.returncode != 0 or "*ERROR" in log or not os.path.exists(dat)
        if bad:
            tail = "\n".join(log.strip().splitlines()[-25:])
            raise CcxError("ccx failed for %s (exit %d); last lines of its output:\n%s"
                           % (label, proc.returncode, tail))
        with open(dat) as f:
            result = parse_dat(f.read())
        if keep_dir:
            os.makedirs(keep_dir, exist_ok=True)
            shutil.copy(os.path.join(tmp, "model.inp"), keep_dir)
            with open(os.path.join(keep_dir, "ccx.log"), "w") as f:
                f.write("\n".join(log.splitlines()[-40:]) + "\n")
        return result
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def run_from_rest(ccx, inp, label, keep_dir=None):
    """run_ccx's times and displacements with the rest state (t = 0, u = 0) first."""
    t, u, _ = run_ccx(ccx, inp, label, keep_dir)
    return (np.concatenate([[0.0], t]),
            {n: np.vstack([np.zeros(3), a]) for n, a in u.items()})


def parse_dat(text):
    """Displacement blocks and stress blocks of a ccx .dat file."""
    times, disp, stress = [], {}, []
    mode, t = None, None
    for line in text.splitlines():
        s = line.strip()
        if not s:
            continue
        if s.startswith("displacements"):
            mode, t = "u", float(s.split()[-1])
            times.append(t)
            continue
        if s.startswith("stresses"):
            mode, t = "s", float(s.split()[-1])
            continue
        if s[0].isalpha():
            mode = None
            continue
        v = s.split()
        if mode == "u":
            disp.setdefault(int(v[0]), []).append([float(x) for x in v[1:4]])
        elif mode == "s":
            stress.append([t] + [float(x) for x in v[2:8]])
    t = np.array(times)
    u = {n: np.array(a) for n, a in disp.items()}
    for n, a in u.items():
        if len(a) != len(t):
            raise CcxError("ccx .dat: node %d has %d samples for %d times" % (n, len(a), len(t)))
    return t, u, np.array(stress)


def von_mises(s):
    sxx, syy, szz, sxy, sxz, syz = s.T
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2)
                   + 3.0 * (sxy ** 2 + sxz ** 2 + syz ** 2))


# ----------------------------------------------------------------------------
# Sampling


def catmull_rom(t_grid, y, t):
    """Catmull-Rom cubic through (t_grid, y) (uniform t_grid) at times t."""
    dt = t_grid[1] - t_grid[0]
    n = len(t_grid)
    m = np.empty_like(y)
    m[1:-1] = 0.5 * (y[2:] - y[:-2])
    m[0], m[-1] = y[1] - y[0], y[-1] - y[-2]
    i = np.clip(((t - t_grid[0]) / dt).astype(int), 0, n - 2)
    s = ((t - t_grid[i]) / dt)[:, None]
    h00, h10 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s
    h01, h11 = -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    return h00 * y[i] + h10 * m[i] + h01 * y[i + 1] + h11 * m[i + 1]


def sample_times(end_time, rng):
    k = np.arange(int(round(end_time * FS)) + 1)
    t = (k + rng.uniform(-0.2, 0.2, size=k.size)) / FS
    return np.sort(np.clip(t, 0.0, end_time))


def pick_markers(mesh, count, rng):
    """Surface grid nodes, one per stretch of the length (the last stretch
    reaches the tip), never on the clamped face."""
    cand = mesh.surface_grid_nodes()
    by_i = {}
    for nid in cand:
        by_i.setdefault(mesh.nodes[nid][0] // 2, []).append(nid)
    columns = sorted(by_i)
    out = []
    for chunk in np.array_split(np.array(columns), count):
        pool = [nid for i in chunk for nid in by_i[int(i)]]
        out.append(int(rng.choice(pool)))
    return out


def tip_probe(mesh):
    nx, ny, nz = mesh.n
    return mesh.nid(2 * nx, ny if ny % 2 == 0 else ny - 1, nz if nz % 2 == 0 else nz - 1)


# ----------------------------------------------------------------------------
# Outputs


def deck_text(case):
    nx, ny, nz = case["n"]
    h = case["h"]
    L, W, H = nx * h, ny * h, nz * h
    E_nom = case["E_true"] * case["E_factor"]

    def vec(v):
        return "[%s]" % ", ".join("%.9g" % x for x in v)

    return "\n".join([
        "# Blind case %s: nominal deck (one effect, if any, is left out)." % case["name"],
        "[simulation]",
        'name = "blind-%s"' % case["name"],
        "dt = %.9g" % case["dt"],
        "end_time = %.9g" % case["end_time"],
        "gravity = %s" % vec(case["g_deck"]),
        "", "[domain]", "voxel_size = %.9g" % h, "padding = 1",
        "", "[[geometry]]", 'type = "box"', "lo = [0, 0, 0]", "hi = %s" % vec([L, W, H]),
        "", "[material]", 'model = "stvk"',
        "youngs_modulus = %.9g" % E_nom, "poisson_ratio = %.9g" % case.get("nu_deck", NU), "density = %.9g" % RHO,
        "", "[[fixed]]", "lo = [-1, -1, -1]", "hi = [%.9g, 1, 1]" % (0.1 * h),
        "", "[[force]]", "lo = [%.9g, -1, -1]" % (L - 0.5 * h), "hi = %s" % vec([L + 1, 1, 1]),
        "force = %s" % vec(case["force"]), "start = 0", "end = %.9g" % T_RELEASE, ""]
        + sum([["", "[[force]]", "lo = [%.9g, -1, -1]" % (L - 0.5 * h),
                "hi = %s" % vec([L + 1, 1, 1]), "force = %s" % vec(f),
                "start = %.9g" % t0, "end = %.9g" % t1]
               for t0, t1, f in case["pulses"]], []) + [""])


def write_recording(path, mesh, markers, t, u, noise, rng):
    with open(path, "w") as f:
        f.write("marker,X,Y,Z,t,x,y,z\n")
        for m, nid in enumerate(markers):
            X = np.array(mesh.xyz(nid))
            pos = X + u[nid] + rng.normal(0.0, noise, size=u[nid].shape)
            for k in range(len(t)):
                f.write("%d,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n"
                        % (m, X[0], X[1], X[2], t[k], pos[k, 0], pos[k, 1], pos[k, 2]))


def motion_summary(t, u_tip):
    """Tip amplitude, first frequency from zero crossings after the release,
    final offset and amplitude decay ratio."""
    free = t > T_RELEASE + 0.05
    comp = int(np.argmax(np.std(u_tip[free], axis=0)[1:])) + 1
    s = u_tip[free, comp]
    tf = t[free]
    mean = s.mean()
    x = s - mean
    cross = tf[:-1][np.sign(x[:-1]) * np.sign(x[1:]) < 0]
    freq = (len(cross) - 1) / (2 * (cross[-1] - cross[0])) if len(cross) > 2 else float("nan")
    half = len(x) // 2
    decay = np.ptp(x[half:]) / max(np.ptp(x[:half]), 1e-30)
    last = tf > tf[-1] - 0.5
    return dict(tip_amplitude=float(np.max(np.linalg.norm(u_tip, axis=1))),
                component="xyz"[comp], freq_hz=float(freq),
                final_offset=float(s[last].mean()), decay_ratio=float(decay))


# ----------------------------------------------------------------------------
# generate


def prepare_plasticity(case, mesh, ccx, nodes):
    """Yield stress from the peak elastic von Mises stress near the clamp."""
    inp = write_inp(case, mesh, "reference", nodes, 0.6, clamp_stress=True)
    _, _, s = run_ccx(ccx, inp, case["name"] + " (elastic reference for the yield stress)")
    peak = float(von_mises(s[:, 1:]).max())
    case["params"] = {"yield_stress": case["yield_fraction"] * peak,
                      "hardening": case["hardening_fraction"] * case["E_true"]}
    case["notes"] = ("yield_stress = %.2f x peak elastic von Mises in the second element "
                     "layer from the clamp (%.4g Pa)"
                     % (case["yield_fraction"], peak))


def generate_case(case, out_dir, ccx, element, reference, separability=False):
    rng = np.random.default_rng(case["seed"])
    mesh = Mesh(case["n"], case["h"], element)
    markers = pick_markers(mesh, case["markers"], rng)
    tip = tip_probe(mesh)
    nodes = sorted(set(markers) | {tip})
    cdir = os.path.join(out_dir, case["name"])
    os.makedirs(cdir, exist_ok=True)
    t0 = time.time()
    if case["effect"] == "plasticity":
        prepare_plasticity(case, mesh, ccx, nodes)
    inp = write_inp(case, mesh, "truth", nodes, case["end_time"])
    tc, uc = run_from_rest(ccx, inp, case["name"], keep_dir=os.path.join(cdir, "ccx"))
    summary = motion_summary(tc, uc[tip])
    ts = sample_times(case["end_time"], rng)
    us = {n: catmull_rom(tc, uc[n], ts) for n in markers}
    need_ref = case["effect"] in ("plasticity", "material_law") or (
        reference == "all" and case["effect"] is not None)
    if need_ref:
        summary.update(reference_comparison(case, mesh, ccx, nodes, markers, tc, uc, tip))
    write_recording(os.path.join(cdir, "recording.csv"), mesh, markers, ts, us,
                    case["noise"], rng)
    if separability and confounder(case):
        summary.update(separability_check(case, mesh, ccx, nodes, markers, ts, us))
    with open(os.path.join(cdir, "deck.toml"), "w") as f:
        f.write(deck_text(case))
    truth = truth_of(case, element, summary)
    with open(os.path.join(cdir, "truth.json"), "w") as f:
        json.dump(truth, f, indent=2)
    summary["wall_s"] = time.time() - t0
    return truth, summary


def reference_comparison(case, mesh, ccx, nodes, markers, tc, uc, tip):
    """Effect-free run with the same loads: frequency ratio, offset change
    and the marker RMS difference in noise sigmas."""
    inp = write_inp(case, mesh, "reference", nodes, case["end_time"])
    tr, ur = run_from_rest(ccx, inp, case["name"] + " (reference)")
    ref = motion_summary(tr, ur[tip])
    diff = np.sqrt(np.mean([np.mean(np.sum((uc[n] - ur[n]) ** 2, axis=1)) for n in markers]))
    snr = float(diff / case["noise"])
    return dict(ref_freq_hz=ref["freq_hz"], ref_final_offset=ref["final_offset"],
                ref_decay_ratio=ref["decay_ratio"], detect_snr=snr)


def confounder(case):
    """The effect that damps a uniform cantilever like this case's, if any:
    mass-proportional damping (alpha M) and linear drag on the surface (c A_i
    per node) give every bending mode the same damping when alpha = c (P L +
    4 A_tip) / (rho A L) (the modes normalized to mean square 1 along the beam
    have tip value 2; P the perimeter, A the cross-section).  Returns
    (effect, params at that alpha or c, per-unit factor) or None."""
    eff, p = case["effect"], case["params"]
    nx, ny, nz = case["n"]
    h = case["h"]
    L, A, P = nx * h, ny * nz * h * h, 2 * (ny + nz) * h
    alpha_per_c = (P * L + 4 * A) / (RHO * A * L)
    if eff == "air_drag" and p.get("quadratic", 0.0) == 0.0:
        return "damping", "alpha", p["linear"] * alpha_per_c
    if eff == "damping" and p.get("beta", 0.0) == 0.0 and p.get("alpha", 0.0) > 0.0:
        return "air_drag", "linear", p["alpha"] / alpha_per_c
    return None


def confounder_case(case, eff, value):
    params = {"alpha": value, "beta": 0.0} if eff == "damping" else {
        "linear": value, "quadratic": 0.0}
    return dict(case, effect=eff, params=params)


def separability_check(case, mesh, ccx, nodes, markers, ts, us):
    """Can the recording tell this case's effect from its confounder at all?
    The confounder's coefficient is fitted to the noise-free markers (one
    Gauss-Newton step from the modal equivalent, three CalculiX runs); its
    chi-square against them, delta_chi2, bounds what the data can see of the
    difference (E and the other parameters held at the truth; freeing them can
    only lower it).  Two models whose predictions differ by d (in noise sigmas)
    give a likelihood ratio of mean |d|^2 and sd 2|d|, a Vuong-type z of
    |d| / 2: below 1.96 (delta_chi2 < 15.4) a 95 % test separates them less
    often than not, and "ambiguous" is the answer the data support."""
    eff, pname, k0 = confounder(case)
    sigma = case["noise"]

    def run(value):
        c = confounder_case(case, eff, value)
        inp = write_inp(c, mesh, "truth", nodes, case["end_time"])
        tc, uc = run_from_rest(ccx, inp, "%s (confounder %s %s = %.4g)"
                               % (case["name"], eff, pname, value))
        return np.concatenate([(catmull_rom(tc, uc[n], ts) - us[n]).ravel()
                               for n in markers]) / sigma

    d0 = run(k0)
    k1 = 1.25 * k0
    d1 = run(k1)
    g = (d1 - d0) / (k1 - k0)
    k2 = max(k0 - float(g @ d0) / float(g @ g), 0.05 * k0)
    d2 = run(k2)
    tried = [(float(d @ d), k) for d, k in ((d0, k0), (d1, k1), (d2, k2))]
    chi2, k = min(tried)
    return dict(confounder=eff, confounder_parameter=pname, confounder_value=k,
                confounder_modal_value=k0, delta_chi2=chi2,
                separable=bool(chi2 >= SEPARABLE_CHI2))


def truth_of(case, element, summary):
    snr = summary.get("detect_snr")
    detectable = case["effect"] != "material_law" or snr is None or snr >= 3.0
    notes = case["notes"]
    if not detectable:
        notes += ("; markers differ from St. Venant-Kirchhoff by only %.2f noise sigma: "
                  "ambiguous or none is acceptable" % snr)
    return {"effect": case["effect"], "parameters": case["params"],
            "scored_parameters": case["scored"], "region": case["region"],
            "E_true": case["E_true"], "E_nominal": case["E_true"] * case["E_factor"],
            "nu_true": case["nu_true"], "nu_nominal": case["nu_deck"],
            "noise_sigma": case["noise"], "element": element, "notes": notes,
            "detectable": bool(detectable), "detect_snr": snr,
            "gravity": case["g_true"], "tip_force": case["force"],
            "extra_pulses": case["pulses"],
            "release_time": T_RELEASE, "seed": case["seed"],
            "separability": {k: summary[k] for k in (
                "confounder", "confounder_parameter", "confounder_value",
                "confounder_modal_value", "delta_chi2", "separable") if k in summary} or None}


def print_summary(name, truth, s):
    line = ("%-20s %-16s tip %.4f m  f1 %.3f Hz (%s)  final offset %+.5f m  decay %.3f"
            % (name, truth["effect"] or "none", s["tip_amplitude"], s["freq_hz"],
               s["component"], s["final_offset"], s["decay_ratio"]))
    if "ref_freq_hz" in s:
        line += ("  | ref f1 %.3f Hz (ratio %.3f) ref offset %+.5f ref decay %.3f  diff %.1f sigma"
                 % (s["ref_freq_hz"], s["freq_hz"] / s["ref_freq_hz"], s["ref_final_offset"],
                    s["ref_decay_ratio"], s["detect_snr"]))
    if "delta_chi2" in s:
        line += ("  | best %s (%s %.4g, modal %.4g): delta chi2 %.3g, %s"
                 % (s["confounder"], s["confounder_parameter"], s["confounder_value"],
                    s["confounder_modal_value"], s["delta_chi2"],
                    "separable" if s["separable"] else "inseparable"))
    print(line + "  [%.0f s]" % s["wall_s"], flush=True)


def cmd_generate(args):
    ccx = find_ccx(args.ccx)
    rng = np.random.default_rng(args.seed)
    all_cases = {"small": cases_small, "full": cases_full, "plate": cases_plate,
                 "hidden-like": cases_hidden}[args.set](rng)
    cases = [c for c in all_cases if not args.only or c["name"] in args.only]
    unknown = set(args.only or []) - {c["name"] for c in all_cases}
    if unknown:
        sys.stderr.write("unknown case(s) %s; the %s set has: %s\n" % (
            ", ".join(sorted(unknown)), args.set, ", ".join(c["name"] for c in all_cases)))
        return 2
    os.makedirs(args.out, exist_ok=True)
    listed = []
    sep = args.separability == "on" or (args.separability == "auto" and args.set == "full")
    for case in cases:
        try:
            truth, summary = generate_case(case, args.out, ccx, args.element, args.reference,
                                           sep)
        except CcxError as e:
            sys.stderr.write("case %s: %s\n" % (case["name"], e))
            return 1
        print_summary(case["name"], truth, summary)
        listed.append({"name": case["name"], "effect": truth["effect"], "summary": summary})
    write_listing(args, [c["name"] for c in all_cases], listed)
    return 0


def write_listing(args, order, listed):
    """DIR/cases.json; cases of an earlier run with the same set, seed and
    element (e.g. another --only subset) are kept unless regenerated."""
    path = os.path.join(args.out, "cases.json")
    head = {"set": args.set, "seed": args.seed, "element": args.element}
    old = []
    if os.path.exists(path):
        with open(path) as f:
            prev = json.load(f)
        if all(prev.get(k) == v for k, v in head.items()):
            old = prev.get("cases", [])
    by_name = {c["name"]: c for c in old}
    by_name.update({c["name"]: c for c in listed})
    with open(path, "w") as f:
        json.dump(dict(head, cases=[by_name[n] for n in order if n in by_name]), f, indent=2)


# ----------------------------------------------------------------------------
# score

TARGETS = dict(correct=0.9, false_discoveries=0, rms_reduction=0.5, param_error=0.2, iou=0.5)


def box_iou(a, b):
    a, b = np.array(a, float), np.array(b, float)
    lo, hi = np.maximum(a[0], b[0]), np.minimum(a[1], b[1])
    inter = float(np.prod(np.clip(hi - lo, 0.0, None)))
    va, vb = float(np.prod(a[1] - a[0])), float(np.prod(b[1] - b[0]))
    return inter / (va + vb - inter) if va + vb - inter > 0 else 0.0


def mpi_env():
    env = dict(os.environ)
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1",
               OMPI_MCA_btl_vader_single_copy_mechanism="none")
    return env


def run_diagnose(gen4d, cdir, np_):
    cmd = [gen4d, "diagnose", os.path.join(cdir, "deck.toml"),
           "--recording", os.path.join(cdir, "recording.csv"), "--out", os.path.join(cdir, "diag")]
    if np_ > 1:
        cmd = ["mpirun", "-np", str(np_)] + cmd
    shutil.rmtree(os.path.join(cdir, "diag"), ignore_errors=True)
    t0 = time.time()
    proc = subprocess.run(cmd, env=mpi_env(), stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    with open(os.path.join(cdir, "diagnose.log"), "w") as f:
        f.write(proc.stdout)
    return proc, time.time() - t0


def read_report(cdir, sub="diag"):
    with open(os.path.join(cdir, sub, "report.json")) as f:
        rep = json.load(f)
    if not isinstance(rep, dict) or "verdict" not in rep:
        raise ValueError("report.json has no 'verdict'")
    return rep


def reported_effect(rep):
    if rep.get("verdict") == "ambiguous":
        return "ambiguous"
    if rep.get("verdict") == "none":
        return None
    # Missing physics that no effect of the library explained.
    return rep.get("effect") or "unidentified"


def score_case(truth, rep):
    """Per-case results against the truth."""
    eff_t, eff_r = truth["effect"], reported_effect(rep)
    strict = eff_r == eff_t or (not truth.get("detectable", True)
                                and eff_r in (None, "ambiguous"))
    # "ambiguous" between the truth and a confounder that CalculiX showed the data cannot
    # separate from it (truth.json's separability) is the answer the data support.
    sep = truth.get("separability") or {}
    inseparable = (not strict and eff_r == "ambiguous" and sep.get("separable") is False
                   and set(rep.get("contenders") or []) == {eff_t, sep.get("confounder")})
    res = dict(true=eff_t, reported=eff_r, correct=strict or inseparable, strict=strict,
               inseparable=inseparable,
               false_discovery=eff_t is None and rep.get("verdict") == "missing_physics")
    if eff_t is not None and truth.get("detectable", True):
        before, after = rep.get("heldout_rms_before"), rep.get("heldout_rms_after")
        res["rms_reduction"] = (1.0 - after / before) if before and after is not None else None
    if eff_t is not None and (eff_r == eff_t or (inseparable and rep.get("effect") == eff_t)):
        got = rep.get("effect_parameters") or {}
        errs, covered = {}, {}
        for name in truth["scored_parameters"]:
            true = truth["parameters"][name]
            val = (got.get(name) or {}).get("value")
            errs[name] = abs(val - true) / abs(true) if val is not None else None
            ci = (got.get(name) or {}).get("ci95")
            covered[name] = ci[0] <= true <= ci[1] if ci else None
        res["param_errors"] = errs
        # Whether the reported 95 % interval holds the truth (reported, not a target).
        res["ci95_covers"] = covered
        if eff_t == "heterogeneity":
            res["iou"] = box_iou(truth["region"], rep["region"]) if rep.get("region") else 0.0
    return res


def label(effect):
    return "none" if effect is None else str(effect)


def confusion(results):
    rows = sorted({label(r["true"]) for r in results})
    cols = sorted({label(r["true"]) for r in results} | {label(r["reported"]) for r in results}
                  | {"none", "ambiguous"})
    width = max(len(c) for c in cols + rows) + 1
    print("confusion matrix (rows: true effect, columns: reported effect)")
    print(" " * width + "".join(c.rjust(width) for c in cols))
    for row in rows:
        cells = [sum(1 for r in results if label(r["true"]) == row and label(r["reported"]) == c)
                 for c in cols]
        print(row.ljust(width) + "".join(str(v).rjust(width) for v in cells))


def summarize(results):
    """Print the metrics; return (metrics, all targets met)."""
    n = len(results)
    correct = sum(r["correct"] for r in results) / n if n else 0.0
    strict = sum(r.get("strict", r["correct"]) for r in results)
    fd = sum(r["false_discovery"] for r in results)
    ok = correct >= TARGETS["correct"] and fd <= TARGETS["false_discoveries"]
    print("\nfraction correct effect: %.3f (target >= %.2f)" % (correct, TARGETS["correct"]))
    print("  the effect named alone: %d of %d; ambiguous between the truth and a confounder "
          "the data cannot separate from it (truth.json separability): %d"
          % (strict, n, sum(bool(r.get("inseparable")) for r in results)))
    print("false discoveries on null cases: %d (target %d)" % (fd, TARGETS["false_discoveries"]))
    print("\n%-22s %-16s %-16s %8s %10s %s" % ("case", "true", "reported", "rms red.",
                                             "wall s", "parameter errors / IoU"))
    for r in results:
        red = r.get("rms_reduction", "-")
        if "rms_reduction" in r:
            ok &= red is not None and red >= TARGETS["rms_reduction"]
        extra = []
        for name, e in (r.get("param_errors") or {}).items():
            ok &= e is not None and e <= TARGETS["param_error"]
            cov = (r.get("ci95_covers") or {}).get(name)
            extra.append("%s %s%s" % (name, "missing" if e is None else "%.1f%%" % (100 * e),
                                      "" if cov is None else
                                      " (ci95 holds the truth)" if cov else " (ci95 misses it)"))
        if "iou" in r:
            ok &= r["iou"] >= TARGETS["iou"]
            extra.append("IoU %.2f" % r["iou"])
        if r.get("error"):
            extra.append("ERROR: " + r["error"])
        red_s = red if isinstance(red, str) else ("none" if red is None else "%.1f%%" % (100 * red))
        if r.get("inseparable"):
            extra.append("inseparable from its confounder")
        print("%-22s %-16s %-16s %8s %10.1f %s" % (r["case"], label(r["true"]),
                                                  label(r["reported"]), red_s,
                                                  r["wall_s"], "; ".join(extra)))
    cover = [c for r in results for c in (r.get("ci95_covers") or {}).values() if c is not None]
    if cover:
        print("\nreported 95 %% intervals holding the true parameter: %d of %d"
              % (sum(cover), len(cover)))
    print("\ntargets: rms reduction >= %.0f%%, parameters within %.0f%%, IoU >= %.1f"
          % (100 * TARGETS["rms_reduction"], 100 * TARGETS["param_error"], TARGETS["iou"]))
    return dict(fraction_correct=correct, false_discoveries=fd), bool(ok)


def cmd_score(args):
    if not args.reports and not (args.gen4d and os.path.exists(args.gen4d)):
        sys.stderr.write("gen4d not found: %s\n" % args.gen4d)
        return 2
    listing = os.path.join(args.cases, "cases.json")
    if not os.path.exists(listing):
        sys.stderr.write("no cases.json in %s; run 'generate' first\n" % args.cases)
        return 2
    with open(listing) as f:
        names = [c["name"] for c in json.load(f)["cases"]]
    if args.only:
        names = [n for n in names if n in args.only]
    results = []
    for name in names:
        cdir = os.path.join(args.cases, name)
        with open(os.path.join(cdir, "truth.json")) as f:
            truth = json.load(f)
        if args.reports:  # diagnosed already (e.g. one batch job per case): score only
            proc, wall = argparse.Namespace(returncode=0, stdout=""), None
        else:
            proc, wall = run_diagnose(args.gen4d, cdir, args.np)
        try:
            if proc.returncode != 0:
                raise ValueError("gen4d diagnose exited with %d" % proc.returncode)
            rep = read_report(cdir, args.reports or "diag")
            if wall is None:
                wall = rep.get("cost", {}).get("wall_seconds")
            res = score_case(truth, rep)
        except (OSError, ValueError, KeyError, TypeError) as e:
            tail = "\n".join(proc.stdout.strip().splitlines()[-10:])
            print("case %s: no usable report (%s); gen4d exit %d, last output:\n%s"
                  % (name, e, proc.returncode, tail))
            res = dict(true=truth["effect"], reported="failed", correct=False,
                       false_discovery=False, error=str(e))
            if truth["effect"] is not None:
                res["rms_reduction"] = None
        res.update(case=name, wall_s=wall if wall is not None else float("nan"))
        results.append(res)
    confusion(results)
    metrics, ok = summarize(results)
    print("\nall targets met" if ok else "\ntargets NOT met")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(metrics, all_targets_met=ok, cases=results), f, indent=2)
    return 0 if ok else 1


# ----------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate", help="make blind cases with CalculiX")
    g.add_argument("--out", required=True)
    g.add_argument("--set", choices=("small", "full", "plate", "hidden-like"),
                   default="small")
    g.add_argument("--seed", type=int, default=1)
    g.add_argument("--ccx", default="ccx")
    g.add_argument("--element", choices=("C3D20R", "C3D8I", "C3D8"), default="C3D20R",
                   help="CalculiX element (C3D8I and C3D8 are not validated; see the docstring)")
    g.add_argument("--reference", choices=("needed", "all"), default="needed",
                   help="effect-free reference runs: only where needed (plasticity, "
                        "material_law) or for every effect case (summary: frequency ratio, "
                        "marker difference in noise sigmas)")
    g.add_argument("--separability", choices=("auto", "on", "off"), default="auto",
                   help="for damping (mass-proportional) and linear air drag cases, fit the "
                        "other effect with CalculiX and record whether the data can separate "
                        "the two (3 more runs a case; auto: the full set only)")
    g.add_argument("--only", nargs="*", help="generate only these cases")
    s = sub.add_parser("score", help="run gen4d diagnose on the cases and score it")
    s.add_argument("--cases", required=True)
    s.add_argument("--gen4d", help="gen4d to run (not needed with --reports)")
    s.add_argument("--reports", metavar="SUBDIR",
                   help="score the reports already in CASE/SUBDIR/report.json instead of "
                        "running diagnose")
    s.add_argument("--np", type=int, default=1)
    s.add_argument("--json")
    s.add_argument("--only", nargs="*")
    args = ap.parse_args(argv)
    return cmd_generate(args) if args.cmd == "generate" else cmd_score(args)


if __name__ == "__main__":
    sys.exit(main())
