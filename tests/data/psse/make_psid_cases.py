"""Copy PSS/E's own simulation results for small test systems from
NREL-Sienna/PowerSimulationsDynamics.jl (PSID, BSD-3-Clause) into tests/data/psse/<MODEL>/,
for benchmarks/vs_psse.py and tests/test_vs_psse.py.

PSID keeps, in `test/benchmarks/psse/<MODEL>/`, PSS/E raw + dyr files and CSV files
of channels that PSS/E wrote when it simulated them (no header; the meaning of each
column, the event and the units are in PSID's tests `test/test_case*.jl`, restated
in `CASES` below). This script copies the raw and dyr files unchanged (or writes the
dyr file that PSID builds in Julia code, from the parameters in its test), keeps the
compared columns of each CSV, snaps PSS/E's time stamps (written in single
precision: 0.999999 for 1.0) to its 5 ms step, keeps the post-event row where PSS/E
wrote two at the event time, down-samples to `DT` and writes a CSV whose header
names each channel (`vs_psse.CHANNELS`), with `cases.json` (files, event) and a
README naming the source repository, path and commit.

    PYTHONPATH=src:. python tests/data/psse/make_psid_cases.py PSID_GIT_DIR

(PSID_GIT_DIR: a bare git directory of PowerSimulationsDynamics.jl or its `.git`;
`git show <commit>:path` reads it).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
COMMIT = "d94d74e7daaa445517da69cd0d528570fa438f28"
SRC = "test/benchmarks/psse"
DT = 0.02  # s, the down-sampled grid (PSS/E wrote every 5 ms)
STEP = 0.005  # s, PSS/E's time step in these runs

TRIP_12 = {"kind": "branch_trip", "from": 101, "to": 102, "ckt": "1", "t": 1.0}
TRIP_14 = {"kind": "branch_trip", "from": 1, "to": 4, "ckt": "1", "t": 1.0}

# PSS2A/PSS2B: PSID builds the machine, exciter and stabilizer in Julia
# (test_case52_pss2a.jl, test_case53_pss2b.jl) on OMIB.raw + OMIB_GENCLS.dyr; the
# same data as PSS/E dyr records (PSID's `RoundRotorQuadratic` is GENROU, S(1.0) =
# S(1.2) = 0; `TGFixed` is no governor)
_OMIB_GEN = """\
2 'GENCLS' 1 0.0 0.0 /
1 'GENROU' 1 7.0 999.0 0.4 999.0 4.0 0.0 2.2 2.2 0.3 0.3 0.3 0.2 0.0 0.0 /
1 'SEXS' 1 1.0 1.0 120.0 0.4 -10.0 10.0 /
"""
# PSS2A CONs (PSS/E order): TW1 TW2 T6 TW3 TW4 T7 KS2 KS3 T8 T9 KS1 T1 T2 T3 T4
# VSTMAX VSTMIN; ICONs: ICS1 REMBUS1 ICS2 REMBUS2 M N
_PSS2A = (
    "1 'PSS2A' 1 1 0 3 0 5 1 1.5 1.5 0.0 1.5 0.0 1.5 0.1875 1.0 0.5 0.1 2.0 "
    "0.59451 0.0447 0.59451 0.0447 0.1 -0.1 /\n"
)
# PSS2B adds T10 T11 and the input limits VS1MAX VS1MIN VS2MAX VS2MIN
_PSS2B = (
    "1 'PSS2B' 1 1 0 3 0 5 1 1.5 1.5 0.0 1.5 0.0 1.5 0.1875 1.0 0.5 0.1 2.0 "
    "0.59451 0.0447 0.59451 0.0447 1.0 1.0 0.00035 -0.00055 0.915 0.895 0.1 -0.1 /\n"
)

# GAST's and TGOV1's files drive the machine's field through ESAC1A with KC = KD = 0,
# no saturation (E1 = SE1 = E2 = SE2 = 0), KE = 1 and VRMAX/VRMIN (+-10) outside
# VAMAX/VAMIN (+-7): then FEX = 1, VFE = VE = Efd and the model is ESDC1A's block
# diagram term for term (lead-lag TC/TB, KA/(1 + s TA) with non-windup limits
# VAMAX/VAMIN, 1/(s TE) on VR - KE Efd, rate feedback s KF/(1 + s TF) of Efd), the
# only difference AC1A's lower limit 0 on VE, which Efd (2.0 .. 2.6 pu here) never
# reaches. The same record as ESDC1A (CONs TR KA TA TB TC VRMAX VRMIN KE TE KF TF1
# SWITCH E1 SE1 E2 SE2), for a run before smibjax reads ESAC1A:
_ESAC1A_AS_ESDC1A = (
    "    102 'ESDC1A' 1 0.01 200.0 0.05 0.1 0.0 7.0 -7.0 1.0 1.333 0.02 0.8 0 "
    "0.0 0.0 0.0 0.0 /\n"
)


def _as_esdc1a(text: str) -> str:
    """`text` with its ESAC1A record (PSID's GAST/TGOV1 dyr) replaced by
    `_ESAC1A_AS_ESDC1A`."""
    out, skip = [], False
    for line in text.splitlines(keepends=True):
        if "'ESAC1A'" in line:
            skip = True
            out.append(_ESAC1A_AS_ESDC1A)
        elif not skip:
            out.append(line)
        if skip and "/" in line:
            skip = False
    return "".join(out)


# folder: [(case name, raw, dyr (a PSID file, or ("written", text)), csv, event,
#          [column header per CSV column after time, None to drop])]
CASES = {
    "GENROU": [
        (name, "ThreeBusMulti.raw", dyr, csv, TRIP_12, ["ANGL 102:1"])
        for name, dyr, csv in (
            ("GENROU", "ThreeBus_GENROU.dyr", "TEST_GENROU.csv"),
            ("GENROU NO_SAT", "ThreeBus_GENROU_NO_SAT.dyr", "TEST_GENROU_NO_SAT.csv"),
            (
                "GENROU HIGH_SAT",
                "ThreeBus_GENROU_HIGH_SAT.dyr",
                "TEST_GENROU_HIGH_SAT.csv",
            ),
        )
    ],
    "GENROE": [
        ("GENROE", "ThreeBusMulti.raw", "ThreeBus_GENROE.dyr", "TEST_GENROE.csv")
        + (TRIP_12, ["ANGL 102:1"]),
        (
            "GENROE HIGH_SAT",
            "ThreeBusMulti.raw",
            "ThreeBus_GENROE_HIGH_SAT.dyr",
            "TEST_GENROE_HIGH_SAT.csv",
        )
        + (TRIP_12, ["ANGL 102:1"]),
    ],
    "GENSAL": [
        ("GENSAL", "ThreeBusMulti.raw", "ThreeBus_GENSAL.dyr", "TEST_GENSAL.csv")
        + (TRIP_12, ["ANGL 102:1"]),
    ],
    "GENSAE": [
        ("GENSAE", "ThreeBusMulti.raw", "ThreeBus_GENSAE.dyr", "TEST_GENSAE.csv")
        + (TRIP_12, ["ANGL 102:1"]),
    ],
    "SEXS": [
        (name, "ThreeBusMulti.raw", dyr, csv, TRIP_12)
        + (
            [
                "VOLT 102",
                "PFLOW 101-103:1",
                "QFLOW 101-103:1",
                "PFLOW 103-101:1",
                "QFLOW 103-101:1",
                "EFD 102:1",
                "PMECH 102:1",
            ],
        )
        for name, dyr, csv in (
            ("SEXS", "ThreeBus_SEXS.dyr", "SEXS_RESULTS.csv"),
            ("SEXS TE=0", "ThreeBus_SEXS_noTE.dyr", "SEXS_RESULTS_NoTE.csv"),
        )
    ],
    "IEEEST": [
        (name, "ThreeBusMulti.raw", dyr, csv, TRIP_12, ["EFD 102:1", "VOLT 102"])
        for name, dyr, csv in (
            ("IEEEST", "ThreeBus_IEEEST.dyr", "IEEEST_SEXS_RESULTS_NOFILT.csv"),
            (
                "IEEEST filter",
                "ThreeBus_IEEEST_with_filter.dyr",
                "IEEEST_SEXS_RESULTS_FILT.csv",
            ),
        )
    ],
    "HYGOV": [
        ("HYGOV", "ThreeBusMulti.raw", "ThreeBus_HYGOV.dyr", "HYGOV_RESULTS.csv")
        + (TRIP_12, ["VOLT 102", "ANGL 102:1", "SPD 102:1"]),
    ],
    "GAST": [
        ("GAST", "ThreeBusMulti.raw", dyr, "GAST_TEST.csv")
        + (TRIP_12, ["ANGL 102:1", "EFD 102:1"])
        for dyr in ("ThreeBus_GAST.dyr", ("esdc1a", "ThreeBus_GAST.dyr"))
    ],
    "TGOV1": [
        ("TGOV1", "ThreeBusMulti.raw", dyr, "TEST_TGOV1.csv")
        + (TRIP_12, ["ANGL 102:1", "EFD 102:1"])
        for dyr in ("ThreeBus_TGOV1.dyr", ("esdc1a", "ThreeBus_TGOV1.dyr"))
    ],
    "EXST1": [
        ("EXST1", "TVC_System_32.raw", "TVC_System.dyr", "results_PSSe.csv", TRIP_14)
        + (["VOLT 1", "VOLT 2", "VOLT 3", "VOLT 4", "SPD 2:1", "EFD 2:1"],),
    ],
    # OMIB_SSS.raw says 50 Hz (BASFRQ), but PSS/E's results follow 60 Hz: at 60 Hz
    # smibjax meets them to 2e-5 pu (voltage) and 5e-7 pu (speed), at 50 Hz to 1e-2
    # and 3e-4 (a slower swing); PSID runs the file at 60 Hz. `f_base` overrides it
    "STAB1": [
        ("STAB1", "OMIB_SSS.raw", "OMIB_SSS.dyr", "results_PSSe.csv")
        + ({"kind": "vref", "gen": "1:1", "value": 1.0472, "t": 1.0, "f_base": 60.0},)
        + (["VOLT 1", "SPD 1:1", None],),
    ],
    "PSS2A": [
        ("PSS2A", "OMIB.raw", ("written", _OMIB_GEN + _PSS2A), "results_PSSe.csv")
        + ({"kind": "vref", "gen": "1:1", "value": 1.04691, "t": 1.0},)
        + (["PELEC 1:1", "VOLT 1", "SPEED 1:1"],),
    ],
    "PSS2B": [
        ("PSS2B", "OMIB.raw", ("written", _OMIB_GEN + _PSS2B), "results_PSSe.csv")
        + ({"kind": "vref", "gen": "1:1", "value": 1.04691, "t": 1.0},)
        + (["PELEC 1:1", "VOLT 1", "SPEED 1:1"],),
    ],
}
# what a folder's README says beyond its files
_ESAC1A_NOTE = (
    "PSS/E ran the machine with ESAC1A (KC = KD = 0, no saturation, KE = 1), which "
    "smibjax does not read yet: the `_ESDC1A` dyr is the same exciter written as "
    "ESDC1A (term by term the same block diagram, see make_psid_cases.py)."
)
NOTES = {
    "STAB1": "OMIB_SSS.raw says 50 Hz, but PSS/E's results follow 60 Hz (met to "
    "2e-5 pu at 60 Hz, 1e-2 pu at 50 Hz); cases.json's `f_base` runs it at 60 Hz.",
    "GAST": _ESAC1A_NOTE,
    "TGOV1": _ESAC1A_NOTE,
    "PSS2A": "PSID builds the machine, exciter and stabilizer in Julia code; "
    "`PSS2A.dyr` writes the same data as PSS/E dyr records.",
    "PSS2B": "PSID builds the machine, exciter and stabilizer in Julia code; "
    "`PSS2B.dyr` writes the same data as PSS/E dyr records.",
}
# PSS2A/PSS2B's raw file is PSID's PSS2A/OMIB.raw
RAW_FOLDER = {"PSS2B": "PSS2A"}


def git_show(repo: str, path: str) -> str:
    return subprocess.run(
        ["git", "--git-dir", repo, "show", f"{COMMIT}:{path}"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout


def resample(text: str) -> np.ndarray:
    """PSS/E's rows on its 5 ms grid, the last row where two share a time (the
    post-event network), every `DT` s."""
    rows = []
    for line in text.splitlines():
        try:
            rows.append([float(x) for x in line.split(",")])
        except ValueError:
            continue  # a header line
    a = np.asarray(rows)
    k = np.round(a[:, 0] / STEP).astype(int)
    keep = np.r_[k[1:] != k[:-1], True]
    a, k = a[keep], k[keep]
    a[:, 0] = k * STEP
    every = int(round(DT / STEP))
    return a[(k % every == 0) & (k >= 0)]


def main(repo: str) -> None:
    head = [
        "# PSS/E's own simulation results (from PowerSimulationsDynamics.jl)",
        "",
        "Written by `../make_psid_cases.py` (see its docstring); read by",
        "benchmarks/vs_psse.py and tests/test_vs_psse.py.",
        "Source: github.com/NREL-Sienna/PowerSimulationsDynamics.jl, "
        f"`{SRC}/<MODEL>/`, commit {COMMIT}",
        "(BSD 3-Clause licence, Copyright (c) 2020, 2023 Alliance for Sustainable",
        "Energy, LLC and The Regents of the University of California; the raw and",
        "dyr files are also in",
        "NREL-Sienna/PowerSystemsTestData `psid_tests/psse/`). Only data are",
        "copied, no code.",
        "",
    ]
    for folder, cases in CASES.items():
        out = HERE / folder
        out.mkdir(exist_ok=True)
        spec, readme = [], list(head)
        for name, raw, dyr, csv, event, cols in cases:
            src = f"{SRC}/{RAW_FOLDER.get(folder, folder)}/{raw}"
            (out / raw).write_text(git_show(repo, src))
            files = [f"`{src}`"]
            if isinstance(dyr, tuple) and dyr[0] == "esdc1a":
                name += " (ESAC1A as ESDC1A)"
                dyr_name = dyr[1].replace(".dyr", "_ESDC1A.dyr")
                text = _as_esdc1a(git_show(repo, f"{SRC}/{folder}/{dyr[1]}"))
                (out / dyr_name).write_text(text)
                files.append(f"`{dyr_name}` (ESAC1A written as ESDC1A, see above)")
            elif isinstance(dyr, tuple):
                dyr_name = name.replace(" ", "_") + ".dyr"
                (out / dyr_name).write_text(dyr[1])
                files.append(f"`{dyr_name}` (written from PSID's test parameters)")
            else:
                dyr_name = dyr
                (out / dyr).write_text(git_show(repo, f"{SRC}/{folder}/{dyr}"))
                files.append(f"`{SRC}/{folder}/{dyr}`")
            a = resample(git_show(repo, f"{SRC}/{folder}/{csv}"))
            keep = [0] + [i + 1 for i, c in enumerate(cols) if c is not None]
            header = ["t"] + [c for c in cols if c is not None]
            out_csv = name.split(" (")[0].replace(" ", "_").replace("=", "") + ".csv"
            np.savetxt(
                out / out_csv,
                a[:, keep],
                delimiter=",",
                fmt="%.7g",
                header=",".join(header),
                comments="",
            )
            files.append(f"`{SRC}/{folder}/{csv}` -> `{out_csv}`")
            spec.append(
                {"name": name, "raw": raw, "dyr": dyr_name, "csv": out_csv}
                | {"event": event}
            )
            readme.append(f"- {name}: " + ", ".join(files))
        (out / "cases.json").write_text(json.dumps(spec, indent=1) + "\n")
        if folder in NOTES:
            readme += ["", NOTES[folder]]
        (out / "README.md").write_text("\n".join(readme) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
