#!/usr/bin/env python3
"""Checks gen4d diagnose on the small CalculiX blind set (cases none-1 and damping-alpha).

Usage: check_blind_small.py CASES_DIR

- none-1 (E off, no concealed effect): the verdict must be "none" (no false discovery).
- damping-alpha (mass-proportional Rayleigh damping concealed): damping must be named, alone
  or as one of the two contenders of an "ambiguous" verdict (on a uniform beam, linear air drag
  damps like mass-proportional damping); the held-out rms must drop by at least 50 %; when
  damping is named with a mass-proportional term, alpha must be within 20 % of the truth;
  the effect was kept only after the discretisation check (2h or h/2 rerun) measured the
  voxels' own error, a finite amount below what the effect explains.
"""
import json
import os
import sys


def load(d, case):
    with open(os.path.join(d, case, "diag", "report.json")) as f:
        return json.load(f)


def main():
    d = sys.argv[1]
    ok = True
    none = load(d, "none-1")
    print("none-1: verdict %s, effect %s" % (none["verdict"], none["effect"]))
    if none["verdict"] != "none":
        print("FAIL none-1: a false discovery")
        ok = False
    r = load(d, "damping-alpha")
    with open(os.path.join(d, "damping-alpha", "truth.json")) as f:
        truth = json.load(f)
    named = r["effect"] == "damping" or (
        r["verdict"] == "ambiguous" and "damping" in r.get("contenders", []))
    red = 1 - r["heldout_rms_after"] / r["heldout_rms_before"]
    print("damping-alpha: verdict %s, effect %s, contenders %s, held-out rms reduced %.1f %%"
          % (r["verdict"], r["effect"], r.get("contenders"), 100 * red))
    if not named:
        print("FAIL damping-alpha: damping not named")
        ok = False
    if red < 0.5:
        print("FAIL damping-alpha: held-out rms reduced by less than 50 %")
        ok = False
    if r["effect"] == "damping" and "alpha" in r["effect_parameters"]:
        a = r["effect_parameters"]["alpha"]["value"]
        err = a / truth["parameters"]["alpha"] - 1
        print("damping-alpha: alpha %.4g vs %.4g (%+.1f %%)" % (a, truth["parameters"]["alpha"],
                                                             100 * err))
        if abs(err) > 0.2:
            print("FAIL damping-alpha: alpha off by more than 20 %")
            ok = False
    dc = r["discretisation_check"]
    print("damping-alpha: discretisation check done %s on %s, error %.3g m rms (%.3g noise sd)%s"
          % (dc["done"], dc.get("grid"), dc["error_rms"], dc["error_in_noise_sd"],
             ", an upper bound" if dc["upper_bound"] else ""))
    if not (dc["done"] and dc["error_rms"] > 0 and dc["voxels"] > 0):
        print("FAIL damping-alpha: the effect was kept without the discretisation check")
        ok = False
    print("blind small set: %s" % ("passed" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
