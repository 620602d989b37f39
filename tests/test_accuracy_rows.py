"""The accuracy study's row file, its command, and the committed reports regenerated from the committed rows."""

import gzip
import json
from pathlib import Path

import pytest

from hysbench.benchmarks.cli import main as hysbench
from hysbench.benchmarks.diagnosis_accuracy import accuracy, rows
from hysbench.models.errors import HysbenchError

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results"
STRIDE = accuracy.PLAN_STRIDE


def row(seed, kinds=("delay",), right=True, verdict="none", also=()):
    return {"kinds": list(kinds), "base": "mrpim", "drive": "sines", "seed": seed, "strength_pct": 1.0,
            "effects": {"delay": {"delay_s": 0.01}} if "delay" in kinds else {}, "verdict": verdict, "confirmed": None,
            "also": list(also), "ambiguous_with": [], "remainder": None, "parameters": {}, "parameter_errors": {},
            "parameters_within": False, "right": right, "seconds": 0.5}


def meta(seed, design="balanced"):
    return {"design": design, "seed": seed, "cases": 2, "wall_s": 1.0, "machine": None, "missing_bases": {}}


def stored(plan):
    """A plan as read, without the line numbers ``read_plans`` adds for its messages."""
    return {k: plan[k] for k in ("meta", "rows")}


def test_rows_written_are_read_back_the_same_and_storing_a_plan_replaces_only_its_rows(tmp_path):
    path = tmp_path / "rows.jsonl.gz"
    one = {"meta": meta(1), "rows": [row(STRIDE), row(STRIDE + 1, ("null-white",), verdict="delay", right=False)]}
    two = {"meta": meta(2), "rows": [row(2 * STRIDE, also=("creep",)), row(2 * STRIDE + 1)]}
    two["rows"][0]["parameter_errors"] = {"delay_s": float("inf")}  # not computed: stored as null (strict JSON)
    rows.write_plans(path, {"balanced-1": one, "balanced-2": two})
    back = rows.read_plans(path)
    assert list(back) == ["balanced-1", "balanced-2"]
    assert stored(back["balanced-1"]) == one
    assert back["balanced-2"]["lines"] == {"file": str(path), "meta": 4, "rows": [5, 6]}
    assert back["balanced-2"]["rows"][0]["parameter_errors"] == {"delay_s": None}
    lines = gzip.decompress(path.read_bytes()).decode().splitlines()
    assert [json.loads(x)["plan"] for x in lines] == ["balanced-1"] * 3 + ["balanced-2"] * 3
    assert all(("meta" in json.loads(x)) != ("row" in json.loads(x)) for x in lines)
    assert {json.loads(x)["format"] for x in lines} == {rows.ROWS_FORMAT}
    before = path.read_bytes()
    rows.write_plans(path, rows.read_plans(path))
    assert path.read_bytes() == before  # the same plans: the same bytes (no time stamp)
    new_one = [row(STRIDE, verdict="delay")]
    rows.store_plan(path, "balanced-1", meta(1), new_one)
    after = rows.read_plans(path)
    assert list(after) == ["balanced-1", "balanced-2"] and after["balanced-1"]["rows"] == new_one
    assert stored(after["balanced-2"]) == stored(back["balanced-2"])
    rows.store_plan(path, "within-limits-3", meta(3, "within-limits"), [row(3 * STRIDE)])
    assert list(rows.read_plans(path)) == ["balanced-1", "balanced-2", "within-limits-3"]
    assert [p["id"] for p in rows.plan_rows(rows.read_plans(path), ["within-limits-3", "balanced-1"])] == [
        "within-limits-3", "balanced-1"]
    with pytest.raises(HysbenchError, match="no plan balanced-9"):
        rows.plan_rows(rows.read_plans(path), ["balanced-9"], path)
    assert rows.read_plans(tmp_path / "none.jsonl.gz") == {}


def _lines(path):
    return [json.loads(x) for x in gzip.decompress(path.read_bytes()).decode().splitlines()]


def _write_lines(path, entries):
    path.write_bytes(gzip.compress(b"".join((e if isinstance(e, bytes) else json.dumps(e).encode()) + b"\n"
                                            for e in entries), mtime=0))


def _on_plan(path):
    """A row file of two plans, one of them on a user's dataset: lines 1-3 and 4-5."""
    on = {"dataset": "data/x", "name": "x", "model": "mrpim",
          "own": {"verdict": "none", "also": [], "reason": "r", "confirmed": None}}
    rows.write_plans(path, {"balanced-2": {"meta": meta(2), "rows": [row(2 * STRIDE), row(2 * STRIDE + 1)]},
                            "on-x-3": {"meta": {**meta(3), "on": on}, "rows": [row(3 * STRIDE)]}})


def _edit(line, change):
    """A damage to one line of the file (1-based), made on its parsed JSON."""
    def damage(entries):
        change(entries[line - 1])
        return entries
    return damage


def _raw(change):
    """A damage to the file's bytes."""
    return change


# damage, then the words the one-line message holds besides the file's name
DAMAGES = {
    "meta field missing": (_edit(1, lambda e: e["meta"].pop("cases")), "line 1: meta has no field 'cases'"),
    "meta field of the wrong type": (_edit(1, lambda e: e["meta"].update(seed="2")),
                                     "line 1: meta field 'seed' must be an integer >= 0, got \"2\""),
    "unknown design": (_edit(1, lambda e: e["meta"].update(design="random")), "line 1: meta field 'design' must be"),
    "machine of the wrong type": (_edit(1, lambda e: e["meta"].update(machine={"cpu_count": 2, "load_start": "x",
                                                                             "load_end": 0.1})),
                                  "line 1: meta field 'machine.load_start' must be a number"),
    "dataset's own verdict missing": (_edit(4, lambda e: e["meta"]["on"]["own"].pop("verdict")),
                                      "line 4: meta has no field 'on.own.verdict'"),
    "row field missing": (_edit(3, lambda e: e["row"].pop("right")), "line 3: row has no field 'right'"),
    "row field of the wrong type": (_edit(2, lambda e: e["row"].update(right=1)),
                                    "line 2: row field 'right' must be true or false, got 1"),
    "empty kinds": (_edit(5, lambda e: e["row"].update(kinds=[])), "line 5: row field 'kinds' must be a non-empty"),
    "trace of the wrong shape": (_edit(2, lambda e: e["row"].update(trace=[["also"]])),
                                 "line 2: row field 'trace' must be a list of"),
    "row of another format version": (_edit(3, lambda e: e.update(format="hysbench-accuracy-rows/2")),
                                      "line 3: field 'format' is \"hysbench-accuracy-rows/2\"; this hysbench reads"),
    "no plan id": (_edit(2, lambda e: e.pop("plan")), "line 2: field 'plan' must be a plan id"),
    "both meta and row": (_edit(2, lambda e: e.update(meta=meta(2))), "line 2: needs exactly one of"),
    "row not an object": (_edit(2, lambda e: e.update(row=[1])), "line 2: field 'row' must be an object"),
    "a row before its meta line": (lambda entries: [entries[1], entries[0], *entries[2:]],
                                   "line 1: a row of plan balanced-2 before its meta line"),
    "a second meta line": (lambda entries: [*entries[:3], entries[0], *entries[3:]],
                           "line 4: a second meta line for plan balanced-2 (the first is line 1)"),
    "not JSON": (lambda entries: [*entries[:2], b'{"plan": "balanced-2", "row": {', *entries[3:]],
                 "line 3: not JSON"),
    "not an object": (lambda entries: [*entries[:1], b"[1, 2]", *entries[2:]], "line 2: not a JSON object"),
    "truncated gzip": (_raw(lambda raw: raw[:len(raw) // 2]), "truncated: the gzip stream ends inside line"),
    "damaged gzip": (_raw(lambda raw: raw[:20] + bytes(b ^ 0xFF for b in raw[20:60]) + raw[60:]),
                     "damaged: the gzip stream cannot be read past line 1"),
    "not gzip": (_raw(lambda raw: gzip.decompress(raw)), "not a gzip-compressed accuracy row file"),
    "empty": (_raw(lambda raw: b""), "empty, not a gzip-compressed accuracy row file"),
    "last line cut short": (_raw(lambda raw: gzip.compress(gzip.decompress(raw)[:-5], mtime=0)),
                            "line 5: the last line is cut short"),
}


def damaged(tmp_path, name):
    """A row file (``_on_plan``) with the damage ``name``; (path, the words its message holds)."""
    path = tmp_path / "rows.jsonl.gz"
    _on_plan(path)
    damage, words = DAMAGES[name]
    if damage.__name__ == "damage" or name in ("a row before its meta line", "a second meta line", "not JSON",
                                               "not an object"):
        _write_lines(path, damage(_lines(path)))
    else:
        path.write_bytes(damage(path.read_bytes()))
    return path, words


@pytest.mark.parametrize("name", DAMAGES)
def test_a_damaged_row_file_is_refused_in_one_line_naming_the_file_the_line_and_the_field(tmp_path, name):
    path, words = damaged(tmp_path, name)
    with pytest.raises(rows.RowFileError) as e:
        rows.read_plans(path)
    message = str(e.value)
    assert message.startswith(str(path)) and words in message and "\n" not in message, message


@pytest.mark.parametrize("name", ["row field of the wrong type", "row of another format version", "not JSON",
                                  "truncated gzip", "meta field missing", "not gzip"])
@pytest.mark.parametrize("action", ["list", "report", "pool", "limits", "again", "run"])
def test_every_command_that_reads_the_row_file_refuses_a_damaged_one_with_exit_2_and_writes_nothing(
        tmp_path, capsys, monkeypatch, action, name):
    """One line naming the file, the line and the field; no case run, the row file untouched, nothing written."""
    monkeypatch.setattr(accuracy, "run_case", lambda case: pytest.fail("a case was run"))
    path, words = damaged(tmp_path, name)
    before = path.read_bytes()
    args = {"list": [], "report": ["balanced-2", "--report", str(tmp_path / "r.md")],
            "pool": ["balanced-2", "--report", str(tmp_path / "r.md")],
            "limits": ["balanced-2", "--out", str(tmp_path / "limits.json")], "again": ["balanced-2", "--jobs", "1"],
            "run": ["--seed", "2", "--cases", "2", "--jobs", "1", "--report", str(tmp_path / "r.md")]}[action]
    code = hysbench(["accuracy", action, *args, "--rows", str(path)])
    captured = capsys.readouterr()
    err = captured.err
    assert code == 2 and err.count("\n") == 1 and str(path) in err and words in err, err
    assert "Traceback" not in err and captured.out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rows.jsonl.gz"] and path.read_bytes() == before


def test_lines_without_a_format_are_read_as_the_one_format():
    """hysbench 0.2.0 wrote the same layout without "format" (as the committed row file): read as it."""
    lines = gzip.decompress((RESULTS / rows.ROWS_FILE.name).read_bytes()).decode().splitlines()
    assert all("format" not in json.loads(x) for x in lines[:50])
    assert len(rows.read_plans(RESULTS / rows.ROWS_FILE.name)) > 30


def test_a_report_of_rows_without_the_fields_it_reads_names_the_line_and_the_field(tmp_path, capsys):
    """Rows with only the fields the limits read (kinds, base, drive, seed, strength_pct, right) serve
    ``limits``; ``report``, ``pool`` and ``again`` name the first row and field they lack."""
    path = tmp_path / "rows.jsonl.gz"
    least = {k: row(2 * STRIDE)[k] for k in rows.CASE_KEYS}
    rows.write_plans(path, {"balanced-2": {"meta": meta(2), "rows": [least]}})
    for action, more in (("report", ["--report", str(tmp_path / "r.md")]), ("pool", []), ("again", ["--jobs", "1"])):
        assert hysbench(["accuracy", action, "balanced-2", "--rows", str(path), *more]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{path}, line 2: row has no field 'verdict' (plan balanced-2, case 0)" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rows.jsonl.gz"]


@pytest.mark.parametrize("plan, named", [
    ({"meta": meta(1), "rows": []}, "has no rows"),
    ({"meta": {"seed": 1}, "rows": [row(STRIDE)]}, "rows.jsonl.gz, line 1: meta has no field 'design'"),
    ({"meta": meta(1), "rows": [{k: v for k, v in row(STRIDE).items() if k != "base"}]},
     "rows.jsonl.gz, line 2: row has no field 'base'"),
])
@pytest.mark.parametrize("action", [["limits"], ["report"], ["pool"], ["again"]])
def test_a_stored_plan_without_its_rows_or_fields_is_refused_before_anything_is_written(tmp_path, capsys, action,
                                                                                      plan, named):
    path = tmp_path / "rows.jsonl.gz"
    rows.write_plans(path, {"balanced-1": plan})
    before = path.read_bytes()
    out = ["--out", str(tmp_path / "limits.json")] if action == ["limits"] else (
        ["--report", str(tmp_path / "r.md")] if action != ["again"] else [])
    code = hysbench(["accuracy", *action, "balanced-1", "--rows", str(path), *out])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and named in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rows.jsonl.gz"] and path.read_bytes() == before

def test_plan_ids_and_ranges():
    assert rows.plan_id("balanced", 45) == "balanced-45"
    assert rows.plan_id("balanced", 1, {"name": "virtual-dea", "model": "mrpim", "thorough": True}) == (
        "on-virtual-dea-1-thorough")
    assert rows.plan_id("balanced", 2, {"name": "pzt", "model": "classical-pi", "segments": 4}) == (
        "on-pzt-2-classical-pi-segments4")
    assert rows.expand(["balanced-35..37", "on-x-1"]) == ["balanced-35", "balanced-36", "balanced-37", "on-x-1"]
    with pytest.raises(HysbenchError, match="NAME-A..B"):
        rows.expand(["balanced-40..3"])


def _committed_numbers(path):
    """A pooled report's JSON without what names the run (its command)."""
    data = json.loads(path.read_text())
    data.pop("command", None)
    return data


@pytest.mark.parametrize("report,args", [
    ("diagnosis_accuracy_pooled", ["balanced-35..44", "--check", "balanced-45..62"]),
    ("diagnosis_accuracy_within_limits", ["within-limits-63..65"]),
])
def test_the_committed_pooled_reports_are_regenerated_from_the_committed_rows(tmp_path, report, args):
    out = tmp_path / f"{report}.md"
    assert hysbench(["accuracy", "pool", *args, "--rows", str(RESULTS / rows.ROWS_FILE.name),
                     "--report", str(out)]) == 0
    assert _committed_numbers(out.with_suffix(".json")) == _committed_numbers(RESULTS / f"{report}.json")
    tables = [p.read_text().split("| plan seed |", 1)[1] for p in (out, RESULTS / f"{report}.md")]
    assert tables[0] == tables[1]


def test_the_committed_headline_report_is_regenerated_from_the_committed_rows(tmp_path):
    out = tmp_path / "diagnosis_accuracy.md"
    assert hysbench(["accuracy", "report", f"balanced-{accuracy.HEADLINE_SEED}",
                     "--rows", str(RESULTS / rows.ROWS_FILE.name), "--report", str(out)]) == 0
    assert out.read_text() == (RESULTS / "diagnosis_accuracy.md").read_text()
    assert json.loads(out.with_suffix(".json").read_text()) == json.loads(
        (RESULTS / "diagnosis_accuracy.json").read_text())


def stand_in(case):
    """``run_case`` without a diagnosis: right unless the case seed is odd."""
    return {**row(case["seed"], case["kinds"], right=case["seed"] % 2 == 0), "base": case["base"],
            "drive": case["drive"]}


def test_a_run_stores_its_plan_in_the_row_file_and_a_rerun_of_it_replaces_its_rows(tmp_path, monkeypatch):
    monkeypatch.setattr(accuracy, "run_case", stand_in)
    path, report = tmp_path / "rows.jsonl.gz", tmp_path / "r.md"
    s = accuracy.run_accuracy(6, 4, path, report, write_every=4)
    assert (s["plan"], s["cases"], s["right"]) == ("balanced-4", 6, 3)
    stored = rows.read_plans(path)["balanced-4"]
    assert [r["seed"] for r in stored["rows"]] == [4 * STRIDE + i for i in range(6)]
    assert stored["meta"]["design"] == "balanced" and "note" not in stored["meta"]  # the partial write replaced
    assert stored["meta"]["code"] == accuracy.diagnosis_code()
    assert f"Diagnosed by code `{accuracy.diagnosis_code()}`" in report.read_text()
    assert "6 cases (`hysbench accuracy run --seed 4 --cases 6`)" in report.read_text()
    accuracy.run_accuracy(3, 5, path, None)
    accuracy.run_accuracy(2, 4, path, None)
    plans = rows.read_plans(path)
    assert list(plans) == ["balanced-4", "balanced-5"] and len(plans["balanced-4"]["rows"]) == 2


def test_a_run_stopped_by_a_failing_case_keeps_the_cases_before_it_and_says_so(tmp_path, monkeypatch):
    def failing(case):
        if case["seed"] % STRIDE == 3:
            raise HysbenchError("a refused case")
        return stand_in(case)

    monkeypatch.setattr(accuracy, "run_case", failing)
    with pytest.raises(HysbenchError, match="a refused case"):
        accuracy.run_accuracy(5, 6, tmp_path / "rows.jsonl.gz", tmp_path / "r.md")
    plan = rows.read_plans(tmp_path / "rows.jsonl.gz")["balanced-6"]
    assert len(plan["rows"]) == 3 and plan["meta"]["note"].startswith("Stopped after 3 of 5 cases")
    assert "Stopped after 3 of 5 cases: a refused case" in (tmp_path / "r.md").read_text()


def test_the_balanced_plan_puts_every_vocabulary_effect_on_every_base_and_drive(monkeypatch):
    monkeypatch.setattr(accuracy, "piezo_available", lambda: True)
    cases = accuracy.plan(200, 0)
    every = {("mrpim", d) for d in ("sines", "triangles", "multisines")} | {
        ("virtual-dea", d) for d in ("sines", "triangles", "multisines")} | {("piezo", "sines")}
    for cause in accuracy.VOCABULARY:
        assert {(c["base"], c["drive"]) for c in cases if c["kinds"] == (cause,)} == every, cause
    drives = [c["drive"] for c in cases]
    assert 0.6 < drives.count("sines") / 200 < 0.72 and drives.count("triangles") > 25 and drives.count("multisines") > 25
    assert [c["seed"] for c in cases] == list(range(200))
    monkeypatch.setattr(accuracy, "piezo_available", lambda: False)
    without = accuracy.plan(200, 0)
    assert all(c["base"] != "piezo" for c in without) and len(without) == 200
    with pytest.raises(ValueError, match="plan design"):
        accuracy.plan(10, 0, design="random")


def test_the_report_says_when_the_piezo_recording_is_missing(monkeypatch, tmp_path):
    """Without ../shared/datasets the plan has no piezo cases: said in the progress, the stored plan and the
    report."""
    monkeypatch.setattr(accuracy, "piezo_available", lambda: False)
    monkeypatch.setattr(accuracy, "run_case", stand_in)
    said = []
    s = accuracy.run_accuracy(8, 0, tmp_path / "rows.jsonl.gz", tmp_path / "r.md", progress=said.append)
    assert "piezo" in s["missing_bases"] and any(m.startswith("no piezo cases") for m in said)
    assert "piezo" in rows.read_plans(tmp_path / "rows.jsonl.gz")["balanced-0"]["meta"]["missing_bases"]
    text = (tmp_path / "r.md").read_text()
    assert "**No piezo cases:**" in text and str(accuracy.PIEZO) in text
    monkeypatch.setattr(accuracy, "piezo_available", lambda: True)
    assert accuracy.missing_bases(("mrpim", "piezo")) == {}


def test_diagnosing_again_replaces_every_row_in_order_and_lists_each_change_by_hand(tmp_path, monkeypatch):
    path = tmp_path / "rows.jsonl.gz"
    first = [row(2 * STRIDE), row(2 * STRIDE + 1, right=False), row(2 * STRIDE + 2)]
    within = [{**row(3 * STRIDE + 1000), "min_strength_pct": {"delay": 0.2}, "attempts": 2}, row(3 * STRIDE + 1)]
    rows.write_plans(path, {"balanced-2": {"meta": meta(2), "rows": first},
                            "within-limits-3": {"meta": {**meta(3, "within-limits"), "note": "x"}, "rows": within},
                            "balanced-4": {"meta": meta(4), "rows": [row(4 * STRIDE)]}})
    new = {2 * STRIDE + 1: ("delay", [], True, [], True), 2 * STRIDE + 2: ("none", ["creep"], True, [], None),
           3 * STRIDE + 1000: ("none", [], True, ["relaxation"], None),  # only "ambiguous with" differs
           3 * STRIDE + 1: ("relaxation", ["delay"], False, [], False)}
    asked = []

    def again(case):
        asked.append(case)
        verdict, also, right, ambiguous, confirmed = new.get(case["seed"], ("none", [], True, [], None))
        return {**row(case["seed"], case["kinds"], right), "verdict": verdict, "also": also,
                "ambiguous_with": ambiguous, "confirmed": confirmed}

    monkeypatch.setattr(accuracy, "run_case", again)
    done = accuracy.again(["balanced-2", "within-limits-3"], path)
    assert [c["seed"] for c in asked] == [2 * STRIDE, 2 * STRIDE + 1, 2 * STRIDE + 2, 3 * STRIDE + 1000,
                                          3 * STRIDE + 1]
    assert asked[3]["min_strength_pct"] == {"delay": 0.2}  # drawn as the plan drew it
    assert [(d["right_before"], d["right_after"]) for d in done] == [(2, 3), (2, 1)]
    stored = "none (also -; ambiguous with -; nothing to confirm)"
    assert done[0]["changes"] == [
        f"delay on mrpim (case seed {2 * STRIDE + 1}): {stored} -> delay (also -; ambiguous with -; confirmed), "
        "right now",
        f"delay on mrpim (case seed {2 * STRIDE + 2}): {stored} -> none (also creep; ambiguous with -; "
        "nothing to confirm)"]
    assert done[1]["changes"] == [
        f"delay on mrpim (case seed {3 * STRIDE + 1000}): {stored} -> none (also -; ambiguous with relaxation; "
        "nothing to confirm)",
        f"delay on mrpim (case seed {3 * STRIDE + 1}): {stored} -> relaxation (also delay; ambiguous with -; "
        "not confirmed), wrong now"]
    plans = rows.read_plans(path)
    assert [r["verdict"] for r in plans["balanced-2"]["rows"]] == ["none", "delay", "none"]
    assert plans["within-limits-3"]["rows"][0]["attempts"] == 2 and "note" not in plans["within-limits-3"]["meta"]
    assert plans["within-limits-3"]["meta"]["code"] == accuracy.diagnosis_code()  # the code that diagnosed again
    assert plans["balanced-4"]["rows"] == [row(4 * STRIDE)]  # not asked for: untouched


def test_a_changed_case_names_the_first_rule_whose_outcome_changed():
    trace = [["simplest-as-good", "delay"], ["also", "nothing"], ["validation", "confirmed"]]
    old = {**row(1, verdict="delay"), "trace": trace}
    also = {**old, "also": ["creep"], "trace": [trace[0], ["also", "creep"], trace[2]]}
    shorter = {**old, "verdict": "none", "trace": [["nothing-passes", "none"]]}
    longer = {**old, "also": ["creep"], "trace": [*trace, ["also-on-validation", "creep not borne out"]]}
    lines = accuracy.verdict_changes([old, old, old, old, row(1)], [also, shorter, longer, {**old, "confirmed": True},
                                                                    {**row(1), "also": ["creep"]}])
    assert [line.rsplit("; ", 1)[-1] for line in lines] == [
        "first rule changed: also: nothing -> also: creep",
        "first rule changed: simplest-as-good: delay -> nothing-passes: none",
        "first rule changed: - -> also-on-validation: creep not borne out",
        "the rule trace is the same",
        "nothing to confirm)"]  # rows without a trace: nothing said of it


def test_the_command_refuses_bad_input_in_one_line_before_any_case_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(accuracy, "run_case", lambda case: pytest.fail("a case was run"))
    path = tmp_path / "rows.jsonl.gz"
    rows.write_plans(path, {"balanced-2": {"meta": meta(2), "rows": [row(2 * STRIDE)]}})
    before = path.read_bytes()
    for argv, message in [
        (["again", "balanced-2", "balanced-7", "--jobs", "1"], "no plan balanced-7"),
        (["run", "--thorough"], "go with --on"),
        (["run", "--on", str(tmp_path / "missing")], "missing"),
        (["run", "--plan", "within-limits", "--cases", "2000"], "at most 1000 cases"),
        (["report", "balanced-3"], "no plan balanced-3"),
        (["limits", "balanced-2..x"], "NAME-A..B"),
    ]:
        assert hysbench(["accuracy", *argv, "--rows", str(path)]) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, (argv, err)
    assert path.read_bytes() == before


def test_every_action_s_help_ends_with_an_example(capsys):
    for action in ("", "run", "report", "pool", "limits", "again", "list"):
        assert hysbench(["accuracy", *([action] if action else []), "--help"]) == 0
        out = capsys.readouterr().out.rstrip().splitlines()
        assert out[-2] == "example:" and out[-1].strip().startswith("hysbench accuracy"), action


def test_list_names_every_stored_plan(tmp_path, capsys):
    path = tmp_path / "rows.jsonl.gz"
    rows.write_plans(path, {"balanced-2": {"meta": meta(2), "rows": [row(2 * STRIDE), row(2 * STRIDE + 1, right=False)]}})
    assert hysbench(["accuracy", "list", "--rows", str(path)]) == 0
    assert capsys.readouterr().out == "balanced-2: 2 cases, 1 right; code not recorded\n"
    plans = {"balanced-2": {"meta": {**meta(2), "code": accuracy.diagnosis_code()}, "rows": [row(2 * STRIDE)]},
             "balanced-3": {"meta": {**meta(3), "code": "0123456789abcdef"}, "rows": [row(3 * STRIDE)]}}
    rows.write_plans(path, plans)
    assert hysbench(["accuracy", "list", "--rows", str(path)]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"balanced-2: 1 cases, 1 right; code {accuracy.diagnosis_code()} (the installed code)",
        "balanced-3: 1 cases, 1 right; code 0123456789abcdef (not the installed code)"]


def test_the_diagnosis_code_fingerprint_follows_the_planted_effects_source(tmp_path, monkeypatch):
    before = accuracy.diagnosis_code()
    edited = tmp_path / "planted.py"
    edited.write_text(Path(accuracy.planted_effects.__file__).read_text() + "\n# edited\n")
    monkeypatch.setattr(accuracy.planted_effects, "__file__", str(edited))
    assert accuracy.diagnosis_code() != before
    monkeypatch.undo()
    assert accuracy.diagnosis_code() == before
