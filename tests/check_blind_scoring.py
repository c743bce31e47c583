#!/usr/bin/env python3
"""Checks the blind set's scoring rules (drivers/validation/diagnose_blind.py) on made-up
truth/report pairs, its modal equivalence of mass damping and surface drag, and its clamp's
consistent foundation springs.

Usage: check_blind_scoring.py PATH/TO/diagnose_blind.py

- An "ambiguous" verdict counts as correct only when its two contenders are the truth and
  the confounder that truth.json's separability check found inseparable; a separable case,
  other contenders, or a confounder named alone stay wrong; the strict count is kept apart.
- "Missing physics, not identified" (effect null) is reported as "unidentified": a false
  discovery on a null case, wrong on an effect case.
- The modal equivalent alpha = c (P L + 4 A_tip) / (rho A L) maps drag to damping and back.
- The clamp_compliance springs hold the root face's translation and its rotation across a
  two-element thickness at a continuous foundation's stiffness (lumped springs: 1.167 times).
- The hidden-like set's cases: the bar, its load, gravity from t = 0 in the recording and
  what each deck leaves out (its recordings take CalculiX 20-35 minutes each: not run here).
"""
import importlib.util
import sys


def main():
    spec = importlib.util.spec_from_file_location("diagnose_blind", sys.argv[1])
    db = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(db)
    failures = []

    def check(cond, what):
        print(("ok   " if cond else "FAIL ") + what)
        if not cond:
            failures.append(what)

    def truth(separable):
        return {"effect": "air_drag", "parameters": {"linear": 8.0, "quadratic": 0.0},
                "scored_parameters": ["linear"], "detectable": True,
                "separability": None if separable is None else {
                    "confounder": "damping", "delta_chi2": 30.0 if separable else 2.0,
                    "separable": separable}}

    def report(verdict, effect, contenders, linear=8.4):
        return {"verdict": verdict, "effect": effect, "contenders": contenders,
                "effect_parameters": {"linear": {"value": linear}} if effect == "air_drag"
                else {"alpha": {"value": 0.7}},
                "heldout_rms_before": 1.0, "heldout_rms_after": 0.1}

    amb = report("ambiguous", "air_drag", ["air_drag", "damping"])
    r = db.score_case(truth(False), amb)
    check(r["correct"] and r["inseparable"] and not r["strict"],
          "ambiguous {truth, inseparable confounder}: correct, not strict")
    check(abs(r["param_errors"]["linear"] - 0.05) < 1e-12,
          "its parameters are scored when the truth is ranked first")
    r = db.score_case(truth(True), amb)
    check(not r["correct"], "ambiguous on a separable case: wrong")
    r = db.score_case(truth(None), amb)
    check(not r["correct"], "ambiguous where separability was not checked: wrong")
    r = db.score_case(truth(False), report("ambiguous", "air_drag", ["air_drag", "gravity"]))
    check(not r["correct"], "ambiguous with another contender: wrong")
    r = db.score_case(truth(False), report("missing_physics", "damping", ["damping"]))
    check(not r["correct"], "the confounder named alone: wrong")
    r = db.score_case(truth(True), report("missing_physics", "air_drag", ["air_drag"]))
    check(r["correct"] and r["strict"] and not r["inseparable"], "the truth named: strict")
    null = dict(truth(None), effect=None, parameters={}, scored_parameters=[])
    r = db.score_case(null, report("ambiguous", "air_drag", ["air_drag", "damping"]))
    check(not r["correct"] and not r["false_discovery"], "null case, ambiguous: wrong")
    # Missing physics that no effect of the library explained ("effect": null).
    unid = report("missing_physics", None, [])
    r = db.score_case(null, unid)
    check(r["reported"] == "unidentified" and not r["correct"] and r["false_discovery"],
          "null case, missing physics not identified: a false discovery")
    r = db.score_case(truth(True), unid)
    check(r["reported"] == "unidentified" and not r["correct"],
          "effect case, missing physics not identified: wrong")

    case = {"effect": "air_drag", "params": {"linear": 8.0, "quadratic": 0.0},
            "n": (20, 4, 4), "h": 0.01}
    eff, name, alpha = db.confounder(case)
    L, A, P = 0.2, 0.04 ** 2, 0.16
    check(eff == "damping" and name == "alpha"
          and abs(alpha - 8.0 * (P * L + 4 * A) / (db.RHO * A * L)) < 1e-12,
          "air drag 8 -> alpha %.4g" % alpha)
    back = db.confounder({"effect": "damping", "params": {"alpha": alpha, "beta": 0.0},
                          "n": (20, 4, 4), "h": 0.01})
    check(back[0] == "air_drag" and abs(back[2] - 8.0) < 1e-12, "and back to linear 8")
    check(db.confounder({"effect": "damping", "params": {"alpha": 0.0, "beta": 2e-3},
                         "n": (20, 4, 4), "h": 0.01}) is None,
          "stiffness-proportional damping has no such confounder")

    # The clamp's foundation: consistent springs carry a continuous foundation's stiffness
    # against the face's rigid motions exactly, where lumped ones overstate its rotation.
    M = db.face_mass_matrix(True)
    check(abs(M.sum() - 1) < 1e-12 and abs(M.sum(1)[0] + 1 / 12) < 1e-12
          and abs(M.sum(1)[4] - 1 / 3) < 1e-12, "serendipity face: rows sum to -1/12, 1/3")
    mesh = db.Mesh((2, 8, 2), 0.01, "C3D20R")
    on_root = lambda axis, side: axis == 0 and side == 0
    k = 1e7
    g = db.Grounds(mesh)
    g.foundation(mesh, on_root, k)
    ground, pairs = {}, {}
    it = iter(g.lines)
    for line in it:  # SPRING1 "e,n" / SPRING2 "e,a,b" rows, then *SPRING, dofs, value
        if line.startswith("*ELEMENT"):
            kind, rows = line.split("TYPE=")[1].split(",")[0], []
            for row in it:
                if row.startswith("*SPRING"):
                    break
                rows.append([int(v) for v in row.split(",")[1:]])
            dofs, value = next(it), float(next(it))
            if dofs.split(",")[0] != "3":
                continue
            for r in rows:
                if kind == "SPRING1":
                    ground[r[0]] = ground.get(r[0], 0.0) + value
                else:
                    pairs[tuple(r)] = pairs.get(tuple(r), 0.0) + value

    def energy(w):  # one direction's springs (all three alike) under the root face's w(node)
        e = sum(c * w(n) ** 2 for n, c in ground.items())
        return 0.5 * (e + sum(c * (w(a) - w(b)) ** 2 for (a, b), c in pairs.items()))

    z = lambda n: mesh.xyz(n)[2] - 0.01  # a rotation about y across the two-element thickness
    area = mesh.areas(on_root)
    exact_rot = 0.5 * k * 0.08 * 0.02 ** 3 / 12
    lumped_rot = 0.5 * k * sum(a * z(n) ** 2 for n, a in area.items())
    check(abs(energy(lambda n: 1.0) - 0.5 * k * 0.08 * 0.02) < 1e-9 * k
          and abs(energy(z) - exact_rot) < 1e-9 * exact_rot,
          "consistent clamp: translation and rotation at the continuous foundation's "
          "stiffness (lumped: %.3f x)" % (lumped_rot / exact_rot))

    # The hidden-like set's scene: the recording's CalculiX input against the nominal deck.
    cases = {c["name"]: c for c in db.cases_hidden(db.np.random.default_rng(1))}
    check(sorted(cases) == ["gravity-left-out", "gravity-left-out-z", "nu-off"],
          "hidden-like set: its three cases")
    for name, c in cases.items():
        mesh = db.Mesh(c["n"], c["h"], "C3D8")
        inp = db.write_inp(c, mesh, "truth", [1], c["end_time"])
        deck = db.deck_text(c)
        grav = [line for line in inp.splitlines() if ",GRAV," in line]
        check(c["n"] == (30, 5, 3) and "hi = [0.3, 0.05, 0.03]" in deck
              and c["force"][0] == 0 and c["force"][1] < 0 and c["force"][2] == 0,
              "%s: a 0.30 x 0.05 x 0.03 m bar, 3 voxels thick, loaded along -y" % name)
        check(len(grav) == 1 and inp.index("*STEP") < inp.index(grav[0])
              and "*STATIC" not in inp and "*INITIAL" not in inp,
              "%s: the recording's gravity acts from t = 0 on the straight, unstressed bar"
              % name)
        nu_inp = float(inp.split("*ELASTIC\n")[1].splitlines()[0].split(",")[1])
        nu_deck = float(deck.split("poisson_ratio = ")[1].split()[0])
        if name == "nu-off":
            check(nu_inp == 0.35 and nu_deck == 0.3 and "gravity = [0, -9.81, 0]" in deck,
                  "nu-off: only nu (0.35 recorded, 0.3 in the deck) and E differ")
        else:
            check(nu_inp == nu_deck == 0.3 and "gravity = [0, 0, 0]" in deck,
                  "%s: the deck leaves the recording's gravity out" % name)
    print("%d failure(s)" % len(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
