"""The hidden-effect matrix's scoring (bench/discrepancy.py): the families accepted as the answer
of a hidden effect, and the rates of issue 34 item 4 from the per-case rows. No I/O."""

from __future__ import annotations

from collections import Counter

import numpy as np


def families(truth: list, lab: str, on=()) -> set:
    """Library effects accepted as the answer for the hidden ``truth`` effects: the library
    table's truth_effects column (truth lab), the effects themselves (library lab); less the
    effects ``on`` in the start design (--start-set: already in the model, their C parameters
    calibrated with the pool, never offered or named)."""
    if lab != "truth":
        return set(truth) - set(on)
    from dampertwin.model.params import EFFECTS_LIBRARY

    return {r.name for r in EFFECTS_LIBRARY.values() if set(r.truth_effects) & set(truth)} - set(on)


def start_on(start_set: dict) -> list:
    """The effects --start-set switches on."""
    return sorted(k.split(".", 1)[1] for k, v in start_set.items() if k.startswith("effects.") and v is True)


def always_on_families(lab: str) -> set:
    """Library effects that approximate physics the truth ALWAYS has (the library table's
    truth_effects that are not hidden effects: gas dissolution, oil heating, the solenoid valve,
    the seal, the fixture, ...): on the truth lab a control carries them too, since the model's
    baseline switches its approximations off. Empty for the library lab."""
    if lab != "truth":
        return set()
    from dampertwin.model.params import EFFECTS_LIBRARY
    from dampertwin.truth.params import OFF_BY_DEFAULT

    on = {t for r in EFFECTS_LIBRARY.values() for t in r.truth_effects} - set(OFF_BY_DEFAULT)
    return families(sorted(on), lab)


def named_beside(row: dict, lab: str) -> bool:
    """The single case's hidden effect's family among the named effects (or the ambiguous group), in
    any place: on the truth lab the always-on physics' families may lead."""
    got = row["effects"] if row["verdict"] == "named" else row["group"] if row["verdict"] == "ambiguous" else []
    return bool(set(got) & families(row["truth"][:1], lab, row.get("start_on", ())))


def foreign(row: dict, lab: str, always: set) -> bool:
    """A named effect outside the hidden effects' families and the always-on physics' (``always``):
    physics the case does not have at all."""
    return row["verdict"] == "named" and not set(row["effects"]) <= families(row["truth"], lab) | always


def lead_figures(rows: list, lab: str) -> dict:
    """What the workflow's first round finds, apart from its gate: the share of single cases whose top-ranked
    candidate is the hidden effect's family, and how much of the gap ABOVE the controls' (the model error a
    case without a hidden effect leaves: their median held-out gap) that candidate closes. The workflow's
    own gate (decision.min_closed) is of the whole held-out gap; these figures say whether a miss is the
    ranking's or the gate's."""
    floor = [r["gap_before"] for r in rows if r["cell"] == "control"]
    single = [r for r in rows if r["cell"] == "single" and families(r["truth"][:1], lab, r.get("start_on", ()))]
    out = {"single_lead_true_rate": (sum(r.get("lead") in families(r["truth"][:1], lab, r.get("start_on", ()))
                                         for r in single) / len(single)) if single else None}
    if floor and single:
        g0 = float(np.median(floor))
        ex = [(r["gap_before"] - r["lead_gap_after"]) / (r["gap_before"] - g0) for r in single
              if r.get("lead_gap_after") is not None and r["gap_before"] > g0]
        out.update({"control_gap_floor": round(g0, 3),
                    "single_above_floor": sum(r["gap_before"] > g0 for r in single),
                    "single_lead_closed_of_excess_median": round(float(np.median(ex)), 3) if ex else None})
    return out


def score(rows: list, args, names: list) -> dict:
    """The matrix's figures from its per-case rows (``one_case``); ``args`` the command's arguments
    (lab, seed, scale, magnitudes, start_set), ``names`` the library candidates of the single cases."""
    def rate(sel, ok):
        sel = [r for r in rows if sel(r)]
        return (sum(ok(r) for r in sel) / len(sel)) if sel else None

    def named_true(r):  # the effect's documented family named (or in the ambiguous group)
        fam = families(r["truth"][:1], args.lab, r["start_on"])
        return (r["verdict"] == "named" and bool(set(r["effects"][:1]) & fam)) or (
            r["verdict"] == "ambiguous" and bool(set(r["group"]) & fam))

    def wrong_name(r):  # a named effect outside every hidden effect's family
        fam = families(r["truth"], args.lab)
        return r["verdict"] == "named" and not set(r["effects"]) <= fam

    def covered(r):  # every family of the single case's effect is on in the start design
        return bool(r["start_on"]) and not families(r["truth"][:1], args.lab, r["start_on"])

    def both_named(r):  # each hidden effect's family among the named effects
        return r["verdict"] == "named" and all(set(r["effects"]) & families([n], args.lab, r["start_on"])
                                               for n in r["truth"])

    def pair_resolvable(r):
        return all(families([n], args.lab, r["start_on"]) for n in r["truth"]) and not r.get("truth_unresolvable")

    always = always_on_families(args.lab)
    named_anywhere = lambda r: named_beside(r, args.lab)  # noqa: E731
    foreign_name = lambda r: foreign(r, args.lab, always)  # noqa: E731
    def visible(r):
        return bool(r.get("visibility")) and r["visibility"]["ratio"] > 1.0
    per_effect = {n: rate(lambda r, n=n: r["cell"] == "single" and r["truth"] == [n], named_true) for n in names}
    counts = {}
    for r in rows:
        counts.setdefault(r["cell"], {}).setdefault(r["verdict"], 0)
        counts[r["cell"]][r["verdict"]] += 1
    named_closed = [r["closed"] for r in rows if r["verdict"] == "named" and r["cell"] in ("single", "pair")]
    out = {
        "lab": args.lab, "cases": len(rows), "counts": counts, "seed": args.seed, "scale": args.scale,
        "magnitudes": args.magnitudes if args.lab == "truth" else None, "start_set": args.start_set,
        "control_false_named_rate": rate(lambda r: r["cell"] == "control", lambda r: r["verdict"] == "named"),
        # truth lab: the truth's always-on physics (gas dissolution, oil heating, ...) is in every control too,
        # with its library approximations off in the start design; a name outside their families (and the
        # hidden effects') is foreign to the truth. always_on_families: the families counted as its physics
        "control_foreign_named_rate": rate(lambda r: r["cell"] == "control", foreign_name),
        "always_on_families": sorted(always),
        "named_effects": {c: dict(sorted(Counter(e for r in rows if r["cell"] == c and r["verdict"] == "named"
                                                 for e in r["effects"]).items()))
                          for c in sorted({r["cell"] for r in rows})},
        "single_named_rate": rate(lambda r: r["cell"] == "single", named_true),
        "single_named_rate_per_effect": per_effect,
        # the figure: among the single cases the workflow's resolvability check calls resolvable
        # (after an `unexplained`: through the model error the calibrated design leaves)
        "single_named_rate_resolvable": rate(lambda r: r["cell"] == "single" and not r.get("truth_unresolvable")
                                             and not covered(r), named_true),
        # ... and against the noise alone (the check a `none` makes)
        "single_named_rate_resolvable_noise": rate(lambda r: r["cell"] == "single"
                                                   and not r.get("truth_unresolvable_noise") and not covered(r),
                                                   named_true),
        # misses the check calls hidden under the model error (resolvable against the noise alone)
        "single_unexplained_under_model_error": sum(1 for r in rows if r["cell"] == "single"
                                                    and r["verdict"] == "unexplained" and not covered(r)
                                                    and r.get("truth_unresolvable")
                                                    and not r.get("truth_unresolvable_noise")),
        # --start-set: single cases whose every family is on in the start design (calibrated, not nameable);
        # the expected answer is none / unexplained, never another family's name
        "single_covered_at_start": sum(1 for r in rows if r["cell"] == "single" and covered(r)),
        "single_covered_quiet_rate": rate(lambda r: r["cell"] == "single" and covered(r),
                                          lambda r: r["verdict"] in ("none", "unexplained")),
        # misses the workflow itself reported as below what the records resolve (its `none`
        # says so); the rate above counts them as misses
        "single_missed_flagged_unresolvable": sum(1 for r in rows if r["cell"] == "single" and r["verdict"] == "none"
                                                  and r.get("truth_unresolvable")),
        "single_wrong_family_rate": rate(lambda r: r["cell"] == "single", wrong_name),
        # the hidden effect's family named beside others (the always-on physics' families lead on this lab)
        "single_named_anywhere_rate": rate(lambda r: r["cell"] == "single", named_anywhere),
        "single_foreign_named_rate": rate(lambda r: r["cell"] == "single", foreign_name),
        # --visibility: among the single cases whose hidden effect moves some record past the workflow's
        # record gate (a model without model error would see it) / the share of such cases
        "single_named_rate_visible": rate(lambda r: r["cell"] == "single" and visible(r), named_true),
        "single_visible_share": rate(lambda r: r["cell"] == "single" and r.get("visibility"), visible),
        "pair_wrong_family_rate": rate(lambda r: r["cell"] == "pair", wrong_name),
        "pair_foreign_named_rate": rate(lambda r: r["cell"] == "pair", foreign_name),
        "pair_both_named_rate": rate(lambda r: r["cell"] == "pair", both_named),
        # the pairs whose effects could both be named: neither covered at the start nor called hidden
        # under the model error by the resolvability check (the single cases' figure, for pairs)
        "pair_both_named_rate_resolvable": rate(lambda r: r["cell"] == "pair" and pair_resolvable(r), both_named),
        "pair_with_a_member_covered_at_start": sum(1 for r in rows if r["cell"] == "pair" and any(
            not families([n], args.lab, r["start_on"]) for n in r["truth"])),
        "pair_magnitude": getattr(args, "pair_magnitude", 1.0) if args.lab == "truth" else None,
        "artefact_unexplained_rate": rate(lambda r: r["cell"] == "artefact", lambda r: r["verdict"] == "unexplained"),
        "artefact_confident_wrong_rate": rate(lambda r: r["cell"] == "artefact", lambda r: r["verdict"] == "named"),
        "median_closed_fraction_named": float(np.median(named_closed)) if named_closed else None,
        # the held-out gap (RMS whitened residual, 1 = noise) the start design leaves: on a control it is the
        # model error of the truth that the calibration refit and the allowances did not absorb
        "median_gap_before": {c: float(np.median([r["gap_before"] for r in rows if r["cell"] == c]))
                              for c in sorted({r["cell"] for r in rows})},
        **lead_figures(rows, args.lab),
    }
    return out
