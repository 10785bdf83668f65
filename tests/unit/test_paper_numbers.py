"""The paper's printed numbers (config/paper/*.csv) against the paper's own text.

The CSVs are checked cell by cell against Tables 3-24 parsed afresh from the paper markdown
(``$AVOA_SHARED_DIR/paper/fahmy2023_avoa_liion.md``, default ``<repo>/../shared``); the tests
skip when that file is absent. The consistency findings listed in config/paper/README.md are
recomputed from the CSVs and pinned here; ``python tests/unit/test_paper_numbers.py`` prints them.
"""

import csv
import os
import re
from collections import defaultdict
from itertools import combinations
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAPER_DIR = REPO / "config" / "paper"
SHARED = Path(os.environ.get("AVOA_SHARED_DIR", str(REPO.parent / "shared")))
PAPER_MD = SHARED / "paper" / "fahmy2023_avoa_liion.md"

ALGORITHMS = ["nelder_mead", "quasi_newton", "ga", "gwo", "run", "avoa", "gto"]
PRINTED_ALGORITHM = {
    "nelder-mead": "nelder_mead",
    "quasi-newton": "quasi_newton",
    "ga": "ga",
    "gwo": "gwo",
    "rk": "run",
    "avoa": "avoa",
    "gto": "gto",
}
PRINTED_PARAMETER = {
    "vnom": "vnom",
    "ro": "r0",
    "q": "q",
    "vdis": "vdis",
    "rtr": "rtr",
    "tautr": "tau",
    "ise": "ise",
}
ROWS_PER_CASE = {
    1: ["vnom", "r0", "q", "vdis"],
    2: ["vnom", "r0", "vdis", "rtr", "tau"],
    3: ["vnom", "r0", "vdis"],
    4: ["vnom", "r0", "vdis", "rtr", "tau"],
}
TABLE_WITHOUT_ISE = 12


def scenario_case(table: int) -> tuple[int, int]:
    """Tables 4-19 run scenario-major: 4 = S1C1, 5 = S1C2, ..., 19 = S4C4."""
    return (table - 4) // 4 + 1, (table - 4) % 4 + 1


# --------------------------------------------------------------------------- the markdown side
def parse_markdown_tables(text: str) -> dict[int, list[list[str]]]:
    """``{N: rows}`` for every line that starts "Table N." followed by tab-separated rows.

    Blank lines inside a table are skipped; the first non-blank line without a tab ends it.
    """
    tables: dict[int, list[list[str]]] = {}
    current: list[list[str]] | None = None
    for line in text.splitlines():
        heading = re.match(r"Table (\d+)\.\s", line)
        if heading:
            number = int(heading.group(1))
            assert number not in tables, f"Table {number} heading appears twice"
            current = tables[number] = []
        elif current is not None:
            if "\t" in line:
                current.append([cell.strip() for cell in line.split("\t")])
            elif line.strip():
                current = None
    return tables


def printed_algorithm(header_cell: str) -> str:
    key = re.sub(r"[\u2010-\u2015]", "-", header_cell).strip().lower()
    return PRINTED_ALGORITHM[key]


def printed_parameter(label: str) -> str:
    """'$V_{nom} T_1$' -> vnom, '$\\tau_{tr} T_2$' -> tau, '<i>ISE</i>' -> ise, 'Q' -> q."""
    plain = re.sub(r"<[^>]+>|[${}\\]", "", label)
    plain = re.sub(r"\s*\(.*\)\s*$", "", plain.strip())  # Table 3 units, e.g. "Q (Ahr)"
    plain = re.sub(r"\s*T_[12]$", "", plain)
    return PRINTED_PARAMETER[plain.replace("_", "").replace(" ", "").lower()]


def smallest_integer(rank_printed: str) -> int:
    return min(int(x) for x in re.findall(r"\d+", rank_printed))


def expected_from_paper(tables: dict[int, list[list[str]]]) -> dict[str, dict]:
    """Every cell of Tables 3-24 keyed the way the CSVs key them; values as printed strings."""
    params, objective, timing, bounds = {}, {}, {}, {}
    for n in range(4, 20):
        header, *rows = tables[n]
        algs = [printed_algorithm(h) for h in header[1:]]
        s, c = scenario_case(n)
        for row in rows:
            p = printed_parameter(row[0])
            for a, v in zip(algs, row[1:], strict=True):
                params[(n, s, c, a, p)] = v
    for n in range(20, 24):
        header, *rows = tables[n]
        algs = [printed_algorithm(h) for h in header[1:]]
        assert len(rows) == 8, f"Table {n}: {len(rows)} rows"
        for k in range(4):
            values, ranks = rows[2 * k], rows[2 * k + 1]
            assert values[0].startswith(f"Case ({k + 1})"), values[0]
            assert ranks[0] == "Rank", ranks[0]
            for a, v, r in zip(algs, values[1:], ranks[1:], strict=True):
                objective[(n, n - 19, k + 1, a)] = (v, r, smallest_integer(r))
    header, time_row = tables[24]
    assert time_row[0] == "Time"
    for h, v in zip(header[1:], time_row[1:], strict=True):
        timing[printed_algorithm(h)] = v
    header, temps, *rows = tables[3]
    assert "T_1 = 25" in temps[1]
    assert "T_2 = 45" in temps[4]
    for row in rows:
        bounds[("T1", printed_parameter(row[0]))] = (row[1], row[2])
        bounds[("T2", printed_parameter(row[3]))] = (row[4], row[5])
    return {"params": params, "objective": objective, "time": timing, "bounds": bounds}


# --------------------------------------------------------------------------- the CSV side
def read_csv(name: str) -> list[dict[str, str]]:
    with open(PAPER_DIR / name, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def actual_from_csvs() -> dict[str, dict]:
    params, objective, timing, bounds = {}, {}, {}, {}
    for r in read_csv("params.csv"):
        key = (int(r["table"]), int(r["scenario"]), int(r["case"]), r["algorithm"], r["parameter"])
        assert key not in params, f"duplicate row {key}"
        params[key] = r["value"]
    for r in read_csv("objective.csv"):
        key = (int(r["table"]), int(r["scenario"]), int(r["case"]), r["algorithm"])
        assert key not in objective, f"duplicate row {key}"
        objective[key] = (r["ise"], r["rank_printed"], int(r["rank"]))
    for r in read_csv("time_per_iteration.csv"):
        timing[r["algorithm"]] = r["seconds"]
    for r in read_csv("bounds.csv"):
        bounds[(r["temperature"], r["parameter"])] = (r["lower"], r["upper"])
    return {"params": params, "objective": objective, "time": timing, "bounds": bounds}


def differences(expected: dict, actual: dict) -> list[str]:
    out = []
    for key in sorted(expected.keys() | actual.keys(), key=str):
        if expected.get(key) != actual.get(key):
            out.append(f"{key}: paper {expected.get(key)!r} vs csv {actual.get(key)!r}")
    return out


# --------------------------------------------------------------------------- consistency checks
def consistency_findings(params: dict, objective: dict, bounds: dict) -> dict[str, list]:
    """Inconsistencies between the paper's own tables, computed from the transcription."""
    value = {k: float(v) for k, v in params.items()}
    findings: dict[str, list] = defaultdict(list)

    # 1. ISE in a parameter table vs the ISE in Tables 20-23 for the same scenario/case/algorithm.
    for (n, s, c, a), (ise, _, _) in sorted(objective.items()):
        t = 4 * (s - 1) + c + 3
        printed = params.get((t, s, c, a, "ise"))
        if printed is None:
            findings["ise_missing_in_parameter_table"].append((t, s, c, a, ise))
        elif float(printed) != float(ise):
            findings["ise_differs"].append((t, n, s, c, a, printed, ise))

    # 2. Printed rank vs the ordering of the printed ISE (ties allow any rank in the tied span).
    by_case = defaultdict(dict)
    for (_, s, c, a), (ise, rank_printed, _) in objective.items():
        by_case[(s, c)][a] = (float(ise), rank_printed)
    for (s, c), algs in sorted(by_case.items()):
        for a, (ise, rank_printed) in algs.items():
            lo = 1 + sum(other < ise for other, _ in algs.values())
            hi = sum(other <= ise for other, _ in algs.values())
            ranks = [int(x) for x in re.findall(r"\d+", rank_printed)]
            if any(not lo <= r <= hi for r in ranks):
                span = str(lo) if lo == hi else f"{lo}-{hi}"
                findings["rank_differs"].append((s, c, a, algs[a][0], rank_printed, span))
            if ("Min." in rank_printed and lo != 1) or ("Max." in rank_printed and hi != len(algs)):
                findings["min_max_label_wrong"].append((s, c, a, rank_printed))

    # 3. Estimates outside Table 3's bounds (case 1-2 at T1, case 3-4 at T2).
    for (n, s, c, a, p), v in sorted(value.items()):
        if p == "ise":
            continue
        lower, upper = (float(x) for x in bounds[("T1" if c <= 2 else "T2", p)])
        if not lower <= v <= upper:
            findings["out_of_bounds"].append((n, s, c, a, p, params[(n, s, c, a, p)]))
        elif v in (lower, upper):
            findings["on_a_bound"].append((n, s, c, a, p, params[(n, s, c, a, p)]))

    # 4. Whole rows (all 7 algorithms) printed identically in two different tables.
    rows = defaultdict(dict)
    for (n, _, _, a, p), v in params.items():
        rows[(n, p)][a] = v
    for (n1, p1), (n2, p2) in combinations(sorted(rows), 2):
        if p1 == p2 and p1 != "ise" and rows[(n1, p1)] == rows[(n2, p2)]:
            findings["identical_rows"].append((n1, n2, p1))

    # 5. Two algorithms with the same printed parameter vector in one table but different ISE
    #    (the model and data are the same, so the same parameters must give the same ISE).
    vectors = defaultdict(dict)
    for (n, _, _, a, p), v in params.items():
        if p != "ise":
            vectors[(n, a)][p] = float(v)
    for n in range(4, 20):
        for a1, a2 in combinations(ALGORITHMS, 2):
            if vectors[(n, a1)] == vectors[(n, a2)]:
                s, c = scenario_case(n)
                ise1 = objective[(19 + s, s, c, a1)][0]
                ise2 = objective[(19 + s, s, c, a2)][0]
                if float(ise1) != float(ise2):
                    findings["same_parameters_different_ise"].append((n, a1, a2, ise1, ise2))
                else:
                    findings["same_parameters_same_ise"].append((n, a1, a2, ise1))

    # 6. One algorithm's whole parameter column repeated in another table: every parameter
    #    printed identically, or one printing extends the other's digits (0.05391 / 0.053914)
    #    with at least 4 decimals, so that values sitting on a bound (3.7, 0.05) do not count.
    def same_printing(x: str, y: str) -> bool:
        short, long = sorted((x, y), key=len)
        return x == y or (long.startswith(short) and len(short.split(".")[-1]) >= 4)

    for (n1, a1), (n2, a2) in combinations(sorted(vectors), 2):
        if n1 == n2 or vectors[(n1, a1)].keys() != vectors[(n2, a2)].keys():
            continue
        if all(same_printing(params[(n1, *scenario_case(n1), a1, p)],
                             params[(n2, *scenario_case(n2), a2, p)])
               for p in vectors[(n1, a1)]):  # fmt: skip
            findings["column_repeated_across_tables"].append((n1, a1, n2, a2))

    # 7. Which algorithm has the smallest printed ISE in each scenario/case.
    for (s, c), algs in sorted(by_case.items()):
        best = min(algs, key=lambda a: algs[a][0])
        if best != "avoa":
            findings["avoa_not_best"].append((s, c, best))
    return dict(findings)


# --------------------------------------------------------------------------- fixtures & tests
@pytest.fixture(scope="module")
def paper():
    if not PAPER_MD.is_file():
        pytest.skip(f"paper markdown not found at {PAPER_MD} (set AVOA_SHARED_DIR)")
    tables = parse_markdown_tables(PAPER_MD.read_text(encoding="utf-8"))
    return tables, expected_from_paper(tables)


@pytest.fixture(scope="module")
def transcribed():
    return actual_from_csvs()


@pytest.mark.parametrize("part", ["params", "objective", "time", "bounds"])
def test_every_cell_matches_the_paper(paper, transcribed, part):
    _, expected = paper
    assert len(expected[part]) > 0
    assert differences(expected[part], transcribed[part]) == []


def test_number_of_cells_checked(paper):
    _, expected = paper
    counts = {part: len(cells) for part, cells in expected.items()}
    # params: 16 tables x 7 algorithms x rows (5, 6, 4, 6 per scenario), minus Table 12's ISE row
    assert counts == {"params": 4 * 7 * (5 + 6 + 4 + 6) - 7, "objective": 4 * 4 * 7, "time": 7,
                      "bounds": 12}  # fmt: skip


def test_an_altered_value_is_caught(paper, transcribed):
    """The comparison is not vacuous: change one printed digit, drop one row, and it fails."""
    _, expected = paper
    altered = dict(transcribed["params"])
    key = (5, 1, 2, "gwo", "rtr")
    assert altered[key] == "0.00549784"
    altered[key] = "0.0054978"  # numerically close, but not the printed string
    assert differences(expected["params"], altered) == [
        f"{key}: paper '0.00549784' vs csv '0.0054978'"
    ]
    del altered[key]
    assert len(differences(expected["params"], altered)) == 1
    objective = dict(transcribed["objective"])
    objective[(22, 3, 2, "gwo")] = ("0.0070", "2", 2)
    assert len(differences(expected["objective"], objective)) == 1


def test_structure_of_the_parameter_tables(paper):
    tables, _ = paper
    parameter_tables = [n for n in range(4, 20) if n in tables]
    assert len(parameter_tables) == 16
    for n in parameter_tables:
        header, *rows = tables[n]
        assert [printed_algorithm(h) for h in header[1:]] == ALGORITHMS, n
        assert all(len(row) == 8 for row in rows), n
        _, c = scenario_case(n)
        expected_rows = ROWS_PER_CASE[c] + ([] if n == TABLE_WITHOUT_ISE else ["ise"])
        assert [printed_parameter(row[0]) for row in rows] == expected_rows, n
    for n in range(20, 25):
        assert [printed_algorithm(h) for h in tables[n][0][1:]] == ALGORITHMS, n


def test_structure_of_the_csvs(transcribed):
    params = transcribed["params"]
    assert {k[0] for k in params} == set(range(4, 20))
    for n in range(4, 20):
        s, c = scenario_case(n)
        cells = {k[3:] for k in params if k[0] == n}
        assert {k[1:3] for k in params if k[0] == n} == {(s, c)}
        expected_rows = ROWS_PER_CASE[c] + ([] if n == TABLE_WITHOUT_ISE else ["ise"])
        assert cells == {(a, p) for a in ALGORITHMS for p in expected_rows}, n
    objective = transcribed["objective"]
    assert set(objective) == {
        (19 + s, s, c, a) for s in range(1, 5) for c in range(1, 5) for a in ALGORITHMS
    }
    for ise, rank_printed, rank in objective.values():
        float(ise)
        assert rank == smallest_integer(rank_printed)
    assert set(transcribed["time"]) == set(ALGORITHMS)
    assert all(float(v) > 0 for v in transcribed["time"].values())


def test_printed_values_are_plain_decimals(transcribed):
    """No float round-trip damage (e.g. '3.7001' must not turn into '3.7000999999999997')."""
    pattern = re.compile(r"\d+(\.\d+)?")
    strings = list(transcribed["params"].values())
    strings += [v[0] for v in transcribed["objective"].values()]
    strings += list(transcribed["time"].values())
    strings += [b for pair in transcribed["bounds"].values() for b in pair]
    bad = [v for v in strings if not pattern.fullmatch(v) or len(v) > 10]
    assert bad == []


EXPECTED_FINDINGS = {
    "ise_missing_in_parameter_table": 7,  # Table 12 (S3C1) has no ISE row
    "ise_differs": 0,
    "rank_differs": 2,
    "min_max_label_wrong": 0,
    "out_of_bounds": 56,
    "on_a_bound": 62,
    "identical_rows": 16,
    "same_parameters_different_ise": 2,
    "same_parameters_same_ise": 1,
    "column_repeated_across_tables": 2,
    "avoa_not_best": 0,
}


def test_consistency_findings_are_those_documented(transcribed):
    findings = consistency_findings(
        transcribed["params"], transcribed["objective"], transcribed["bounds"]
    )
    counts = {k: len(findings.get(k, [])) for k in EXPECTED_FINDINGS}
    assert counts == EXPECTED_FINDINGS, findings


if __name__ == "__main__":
    t = actual_from_csvs()
    for kind, items in consistency_findings(t["params"], t["objective"], t["bounds"]).items():
        print(f"{kind}: {len(items)}")
        for item in items:
            print("   ", item)
