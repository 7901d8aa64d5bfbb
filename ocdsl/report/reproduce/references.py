"""Where each reference number of the index comes from (printed in a paper, a digest, a
published or computed value), the printed study tables, and the index's verdicts."""
from __future__ import annotations

from typing import Any


#: Where each reference value of the index comes from, per (report folder, expect check).
#: ``paper``: printed in the paper (the table or equation is named) - only these go to the
#: index's "paper" column; every other kind (``digest``: the seed digest's own synthetic
#: case or re-implementation; ``published``: a benchmark's published or analytic value;
#: ``computed``: a converged reference computed here) goes to the "other reference" column
#: with its label. ``wrong``: the test that shows the printed value cannot be right (the
#: row then counts as "paper value shown wrong" when ocdsl does not meet it; one that meets
#: an ``at_most`` bound with room to spare counts as "better optimum found").
REFERENCES: dict[tuple[str, str], dict[str, str]] = {
    ("brachistochrone", "tf"): {"kind": "published", "source": "dymos benchmark; the cycloid gives 1.8016031"},
    ("bryson_denham", "objective"): {"kind": "published", "source": "analytic, Bryson & Ho (1975): 4/(9 l)"},
    ("mesh_bryson_denham", "objective"): {"kind": "published", "source": "analytic, Bryson & Ho (1975): 4/(9 l)"},
    ("double_integrator", "tf"): {"kind": "published", "source": "analytic (bang-bang, one switch)"},
    ("minimal_double_integrator", "tf"): {"kind": "published", "source": "analytic (bang-bang, one switch)"},
    ("mesh_double_integrator", "tf"): {"kind": "published", "source": "analytic (bang-bang, one switch)"},
    ("two_phase_double_integrator", "brake.tf"): {"kind": "published", "source": "analytic"},
    ("two_phase_double_integrator", "accelerate.tf"): {"kind": "published", "source": "analytic"},
    ("goddard", "r(tf)"): {"kind": "published", "source": "control-toolbox indirect solution"},
    ("mesh_goddard", "r(tf)"): {"kind": "published", "source": "control-toolbox indirect solution"},
    **{(stem, q): {"kind": "published", "source": "exact bang-bang solution, Meditch (1964)"}
       for stem in ("moon_landing", "mesh_moon_landing") for q in ("objective", "tf", "m(tf)")},
    ("seed0_rendezvous", "tf"): {"kind": "paper", "source": "seed 0, §5.1 and Table 4 row [20, 0, 0] (GPM)"},
    ("seed0_fine", "tf"): {"kind": "digest", "source": "seed 0 issue's band [25.868, 25.873] (finer mesh)"},
    ("seed0_exact_euler", "tf"): {"kind": "digest", "source": "digest's re-implementation with the exact "
                                  "Euler equation (seed_000.md §7.3); the paper prints 25.8727 for eq. (13)"},
    ("seed1_10N_paper", "tf"): {"kind": "paper", "source": "seed 1, Table 5, present method (OCR-reconstructed)"},
    ("seed1_5N_paper", "tf"): {"kind": "paper", "source": "seed 1, Table 6, 5 N"},
    ("seed1_2N_paper", "tf"): {"kind": "paper", "source": "seed 1, Table 6, 2 N"},
    ("seed1_10N_optimal", "time(tf)"): {"kind": "paper", "source": "seed 1, Table 5, indirect reference [36]",
                                        "wrong": "tests/test_seed1_optimal.py::test_optimal_10N"},
    ("seed1_5N_optimal", "time(tf)"): {"kind": "paper", "source": "seed 1, Table 6, 5 N (Fourier-DPSO)",
                                       "wrong": "tests/test_seed1_optimal.py::test_optimal_5N_2N"},
    ("seed1_2N_optimal", "time(tf)"): {"kind": "paper", "source": "seed 1, Table 6, 2 N (Fourier-DPSO)",
                                       "wrong": "tests/test_seed1_optimal.py::test_optimal_5N_2N"},
    ("seed2_strategy1", "m(tf)"): {"kind": "paper", "source": "seed 2, Table 2 row 1 (strategy 1)"},
    ("seed2_strategy1", "tf"): {"kind": "computed", "source": "the time the printed mass implies, "
                                "(M − 149.932)/ṁ (the printed 1036.458 s is inconsistent with it)"},
    **{(stem, q): {"kind": "digest", "source": "digest's synthetic case (seed_004.md §5.3; the paper's "
                   "Table 1 is lost)"}
       for stem in ("seed4_case_A", "seed4_case_B", "seed4_two_burn_nlp") for q in ("n_solutions", "pareto_labels")},
}

#: Printed values a run folder is compared with beyond its expect block (the file's
#: expect holds another reference): report folder -> rows ``{quantity, column, paper,
#: source, tol | rtol, wrong}``, ``column`` a key of result.json (``tf``, ``objective``).
PRINTED_EXTRA: dict[str, list[dict[str, Any]]] = {
    "seed2_strategy1": [{"quantity": "tf", "column": "tf", "paper": 1036.458, "rtol": 5.0e-3,
                         "source": "seed 2, Table 2 row 1 (strategy 1)",
                         "wrong": "tests/test_lander.py::test_strategy1_printed_pair_is_inconsistent"}],
}

#: Paper numbers of study files, compared row by row with ``study.csv``: the study stem ->
#: per row (matched on its parameters) the printed values of ``study.csv`` columns
#: (``tf.<phase>``: that phase's entry of a per-phase ``tf``) and the accepted band per
#: column: ``tol`` (|ocdsl - paper| <= tol), ``rtol`` (relative), ``at_most`` (ocdsl <=
#: paper + tol: the problem is multi-modal and better optima exist). ``wrong``: the test
#: that shows the printed value cannot be right.
_T2 = "tests/test_lander.py::test_strategy1_printed_pair_is_inconsistent"
_T3 = "tests/test_lander.py::test_strategy3_printed_descents_cannot_land"
PAPER_TABLES: dict[str, dict[str, Any]] = {
    "seed0_table4": {
        "label": "Seed 0 Table 4 (GPM)",
        "match": ("x0", "y0", "z0"),
        "columns": {"tf": {"label": "tf", "tol": 5.0e-4}},
        "rows": [
            {"x0": 20, "y0": 0, "z0": 0, "paper": {"tf": 25.8727}, "source": "Table 4"},
            {"x0": 20, "y0": 4, "z0": 0, "paper": {"tf": 26.1674}, "at_most": True, "source": "Table 4",
             "wrong": "tests/test_seed0_pipeline.py::test_table4_row"},
            {"x0": 20, "y0": 4, "z0": 4, "paper": {"tf": 25.9360}, "source": "Table 4"},
            {"x0": 20, "y0": 4, "z0": -5, "paper": {"tf": 25.6607}, "source": "Table 4"},
            {"x0": 25, "y0": -5, "z0": -5, "paper": {"tf": 28.7185}, "at_most": True, "source": "Table 4",
             "wrong": "tests/test_seed0_pipeline.py::test_table4_row"},
        ],
    },
    "seed2_strategy2": {
        "label": "seed2_strategy2",
        "match": ("h_i",),
        "columns": {"tf": {"label": "tf", "rtol": 5.0e-3}, "objective": {"label": "m(tf)", "tol": 0.1}},
        "rows": [{"h_i": h, "paper": {"tf": t, "objective": m}, "source": "seed 2, Table 2",
                  **({"wrong": _T2, "wrong_columns": ["tf"]} if h == 100 else {})}
                 for h, t, m in ((100, 1036.458, 149.932), (50, 1012.252, 152.384), (25, 1001.326, 153.395),
                                 (20, 999.288, 153.575), (15, 997.303, 153.747), (10, 995.371, 153.911),
                                 (5, 993.586, 154.053))],
    },
    "seed2_strategy3": {
        "label": "seed2_strategy3",
        "match": ("h_v",),
        "columns": {"tf.descent": {"label": "tf (braking + vertical descent)", "rtol": 5.0e-3},
                    "objective": {"label": "m(tf)", "tol": 0.1}},
        "rows": [{"h_v": h, "paper": {"tf.descent": round(tb + tv, 3), "objective": m},
                  "source": "seed 2, Table 3 (braking + vertical-descent time)",
                  **({"wrong": _T3} if h != 2 else {})}
                 for h, tb, tv, m in ((5, 959.520, 83.436, 147.140), (4, 963.165, 72.497, 148.195),
                                      (3, 967.450, 61.752, 149.130), (2, 974.204, 46.391, 150.376),
                                      (1, 983.827, 27.584, 151.705))],
    },
}

#: The index's verdicts of a row with a paper value, and of a row with another reference.
REPRODUCED, SHOWN_WRONG, NOT_REPRODUCED = "reproduced", "paper value shown wrong", "not reproduced"
#: an ``at_most`` bound met with room to spare: the paper's optimum is beaten, which shows its
#: search stopped at a worse (or a restricted class's) optimum, not that it printed a wrong
#: number (seed 1's Fourier-series times were "shown wrong" by lower unrestricted optima;
#: unseen51 F5)
BETTER = "better optimum found"
AGREES, DIFFERS = "agrees", "differs"
