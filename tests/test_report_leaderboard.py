"""The report's leaderboard, styles and cells: exact expectations on made-up records.

Per-view d_RMS values are chosen so the Wilcoxon test's answer is known: 24 views where
one method is lower on every view (p ~ 1e-5, significant even after Holm over a few
comparisons), or differences of alternating sign (no significant difference).
"""

from __future__ import annotations

import copy
import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bench.report.cells import model_cell, model_text, number
from bench.report.leaderboard import (
    Column,
    leaderboard_html,
    rank_groups,
    reuse_note,
)
from bench.report.plots import pareto_front, plain
from bench.report.styles import method_styles, style_at
from conftest import made_up_record


def views_record(label, views, model="m", target=100, status="ok", **metrics):
    """A record whose d_rms is the RMS of its per-view values ``views``."""
    d = math.sqrt(sum(v * v for v in views) / len(views))
    r = made_up_record(label, model=model)
    r["status"] = status
    r["job"]["target_faces"] = target
    r["per_view"] = {"d_rms": list(views)}
    r["metrics"] = {**r["metrics"], "d_rms": d, **metrics}
    return r


BASE = [5.0 + 0.1 * k for k in range(24)]


def shifted(delta):
    return [v + delta for v in BASE]


def alternating(size):
    return [v + (size if k % 2 else -size) for k, v in enumerate(BASE)]


def test_a_method_better_on_every_view_is_the_winner():
    records = [views_record("a", BASE), views_record("b", shifted(1.0)),
               views_record("c", shifted(2.0))]
    (g,) = rank_groups(records)
    assert [r["job"]["label"] for r in g.ranked] == ["a", "b", "c"]
    assert g.verdict == "winner" and g.ranks == [1, 2, 3] and g.worse == {"b", "c"}
    assert "1 (winner)" in leaderboard_html(records)


def test_no_significant_difference_is_a_tie_for_first():
    # b's per-view values differ from a's by +-0.5, alternately: d_RMS differs a little,
    # the views do not say which is better
    records = [views_record("a", BASE), views_record("b", alternating(0.5)),
               views_record("c", shifted(3.0))]
    (g,) = rank_groups(records)
    assert g.verdict == "tie"
    assert dict(zip((r["job"]["label"] for r in g.ranked), g.ranks)) == \
        {"a": 1, "b": 1, "c": 3}
    html = leaderboard_html(records)
    assert "1 (winner)" not in html and html.count("1 (tie)") == 2
    assert "tie for first" in html


def test_off_target_results_are_listed_apart_never_ranked():
    off = views_record("z", shifted(-4.0), status="ok, off target")  # lowest d_RMS
    records = [views_record("a", BASE), views_record("b", shifted(1.0)), off]
    (g,) = rank_groups(records)
    assert [r["job"]["label"] for r in g.ranked] == ["a", "b"] and g.off == [off]
    html = leaderboard_html(records)
    assert re.search(r"<tr class='off-target extra'><td>off target</td>", html)


def test_values_under_the_resolution_rank_as_equal_and_show_as_zero():
    assert number("hausdorff_mean", 2e-18) == "0" == number("hausdorff_mean", 9e-14)
    assert number("hausdorff_mean", 3.2e-4) == "0.00032"
    # two d_RMS under 1e-4 (identical renders): tied, not a winner
    same = [1e-6] * 24
    records = [views_record("a", same), views_record("b", [2e-5] * 24)]
    (g,) = rank_groups(records)
    assert g.ranks == [1, 1] and g.verdict != "winner"


def test_peak_memory_is_shown_to_one_megabyte():
    assert number("peak_mb", 0.00390625) == "<1"
    assert number("peak_mb", 0.0) == "<1"
    assert number("peak_mb", 203.61) == "204"


def test_the_summary_across_models_counts_wins_ties_and_losses():
    records = [views_record("a", BASE, model="m1"), views_record("b", shifted(1.0), model="m1"),
               views_record("a", BASE, model="m2"), views_record("b", alternating(.5),
                                                                  model="m2")]
    html = leaderboard_html(records)
    table = html[html.index("id='across-models'"):html.index("</table>")]
    rows = re.findall(r"<tr><td class='method'>.*?</span>(\w+)</td>(.*?)</tr>", table)
    cells = {m: re.findall(r"<td>([^<]*)</td>", rest) for m, rest in rows}
    # method: mean rank, groups, wins, ties for first, losses
    assert cells["a"] == ["1.00", "2", "1", "1", "0"]
    assert cells["b"] == ["1.50", "2", "0", "1", "1"]


def test_an_extra_column_shows_only_when_some_record_has_it(monkeypatch):
    extra = Column("faces_128", "faces at 128 px", "faces", None,
                   lambda r: (r.get("metrics") or {}).get("faces_128"))
    monkeypatch.setattr("bench.report.leaderboard.EXTRA_COLUMNS", [extra])
    records = [views_record("a", BASE), views_record("b", shifted(1.0))]
    assert "faces at 128 px" not in leaderboard_html(records)
    records[0]["metrics"]["faces_128"] = 80
    html = leaderboard_html(records)
    assert "faces at 128 px" in html and "<td>80</td>" in html


def test_a_reused_build_is_labelled_with_the_build_it_reused():
    built = views_record("perceptual-mt", BASE, target=200)
    built["job"]["method"] = "perceptual-mt"
    built["stats"] = {"wall_seconds": 22.5, "mt_cache": "built", "peak_mb": 205.6}
    reused = copy.deepcopy(built)
    reused["job"]["target_faces"] = 100
    reused["stats"] = {"wall_seconds": 0.0068, "mt_cache": "memory", "peak_mb": 0.0}
    note = reuse_note(reused, [built, reused])
    assert "200-face job built in 22.5 s" in note
    assert reuse_note(built, [built, reused]) == ""
    assert "before this run" in reuse_note({**reused, "stats": {"mt_cache": "disk"}}, [reused])
    assert "reused build" in leaderboard_html([built, reused])


def test_sixteen_methods_have_sixteen_different_styles():
    names = [f"method-{k:02d}" for k in range(16)]
    styles = method_styles(names, builtin=[])
    assert len(set(styles.values())) == 16
    assert len({s.colour for s in styles.values()}) == 16
    assert len({(s.colour, s.marker) for s in styles.values()}) == 16
    assert len({style_at(i) for i in range(1040)}) == 1040


def test_a_method_keeps_its_style_whatever_else_the_run_holds():
    builtin = ["qslim", "quadric", "memoryless"]
    one = method_styles(["quadric"], builtin=builtin)
    other = method_styles(["memoryless", "quadric", "plugin-x"], builtin=builtin)
    assert one["quadric"] == other["quadric"]
    assert other["plugin-x"] == style_at(3)


def test_a_model_given_as_an_absolute_path_is_shown_by_its_file_name():
    assert model_text("/home/someone/data/spot.obj") == "spot.obj"
    assert model_text("C:\\Users\\x\\scans\\spot.obj") == "spot.obj"
    assert model_text("/srv/a/spot.obj::texture=/srv/a/t.png") == "spot.obj::texture=/srv/a/t.png"
    assert model_text("meshes/spot.obj") == "meshes/spot.obj" and model_text("bunny") == "bunny"
    cell = model_cell("/home/someone/data/spot.obj")
    assert "title='in folder data'" in cell and "/home" not in cell


@pytest.mark.parametrize("value, text", [(600, "600"), (12000, "12,000"), (0.05, "0.05"),
                                         (0.0001, "0.0001"), (1, "1"), (2.5, "2.5")])
def test_tick_labels_are_plain_numbers(value, text):
    assert plain(value) == text


@given(st.lists(st.tuples(st.floats(0.001, 1000), st.floats(0.001, 1000)), min_size=1,
                max_size=30))
def test_the_pareto_front_is_every_point_nothing_beats(points):
    labelled = [(t, e, str(i)) for i, (t, e) in enumerate(points)]
    front = pareto_front(labelled)

    def beaten(p):
        return any(q[0] <= p[0] and q[1] <= p[1] and (q[0] < p[0] or q[1] < p[1])
                   for q in labelled)

    assert {(t, e) for t, e, _ in front} == {(t, e) for t, e, _ in labelled if not beaten((t, e))}
    assert [p[0] for p in front] == sorted(p[0] for p in front)


def _page(tmp_path, records):
    from bench.report.page import write_report

    run = tmp_path / "run"
    (run / "records").mkdir(parents=True)
    return write_report(run, records).read_text()


def test_the_page_starts_with_the_leaderboard_and_keeps_failures_apart(tmp_path):
    model = "/home/someone/private/data/spot.obj"
    skipped = made_up_record("t", status="skipped", model=model,
                             error="t needs texture coordinates; spot.obj has none")
    failed = made_up_record("f", status="failed", model=model)
    records = [views_record("a", BASE, model=model), views_record("b", shifted(1.0), model=model),
               skipped, failed]
    page = _page(tmp_path, records)
    assert "/home/someone" not in page and "private" not in page.replace("in folder data", "")
    assert page.index("id='leaderboard'") < page.index("id='summary'")
    applicable = page[page.index("<h2>Not applicable</h2>"):page.index("<h2>Failures</h2>")]
    failures = page[page.index("<h2>Failures</h2>"):]
    assert "needs texture coordinates" in applicable and "needs texture" not in failures
    assert "it broke" in failures and "it broke" not in applicable


def test_the_summary_puts_the_key_columns_first_and_hides_the_rest(tmp_path):
    page = _page(tmp_path, [views_record("a", BASE), views_record("b", shifted(1.0))])
    table = page[page.index("id='summary'"):]
    heads = re.findall(r"<th(?: class='more')?>([^<]+)</th>", table[:table.index("</tr>")])
    assert heads[:9] == ["model", "method", "shading", "target_faces", "faces", "d_rms",
                         "flip", "ssim", "seconds"]
    assert "<th class='more'>peak_mb</th>" in table and "<th>d_rms</th>" in table
    assert "class='all-columns'" in page


def test_a_long_ranking_shows_its_first_five_and_the_rest_behind_a_tick():
    records = [views_record(f"m{k}", shifted(k)) for k in range(8)]
    html = leaderboard_html(records)
    table = html[html.index("<table id='lb-0'"):]
    rows = re.findall(r"<tr( class='[^']*')?><td>([^<]*)</td>", table)
    assert [rank for _, rank in rows] == ["1 (winner)", "2", "3", "4", "5", "6", "7", "8"]
    assert ["extra" in cls for cls, _ in rows] == [False] * 5 + [True] * 3
    assert "data-table='lb-0'> all 8 results (3 more)" in html
    # ties for first are never hidden, however many
    tied = [views_record(f"t{k}", alternating(0.01 * k)) for k in range(7)]
    assert "extra" not in leaderboard_html(tied).split("</table>")[1]


def test_a_point_that_reused_a_build_is_hollow_and_off_the_front():
    from bench.report.plots import quality_time_figure

    styles = method_styles(["a", "b"], builtin=[])
    # b's second budget reused a's... b's own build: 0.004 s, which would lead the front
    points = {"a": [(1.0, 10.0, False)], "b": [(5.0, 12.0, False), (0.004, 11.0, True)]}
    fig = quality_time_figure([("t", "d_RMS", points)], styles)
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert [x for x in labels if x.startswith("Pareto")] == ["Pareto front:\n  a"]
    hollow = [c for c in fig.axes[0].collections if len(c.get_offsets()) == 1
              and tuple(c.get_offsets()[0]) == (0.004, 11.0)]
    assert len(hollow) == 1 and hollow[0].get_facecolors().size == 0


def test_the_switch_size_column_shows_bounds_as_bounds():
    records = [views_record("a", BASE), views_record("b", shifted(1.0)),
               views_record("c", shifted(2.0))]
    for record, (value, bound) in zip(records, ((512.0, ">="), (90.6, None), (32.0, "<"))):
        record["screen"] = {"switch_px": {"value": value, "bound": bound},
                            "switch_px_rms": {"value": value, "bound": bound}}
    page = leaderboard_html(records)
    assert "switch px" in page
    cells = [re.sub(r"<[^>]+>", "", c) for c in re.findall(r"<td[^>]*>.*?</td>", page)]
    assert "≥512" in cells and "91" in cells and "&lt;32" in cells
    assert "switch px" not in leaderboard_html([views_record("a", BASE),
                                                views_record("b", shifted(1.0))])


def test_the_screen_section_lists_each_level_and_the_faces_needed():
    from bench.report.images import Inline
    from bench.report.page import _screen_sizes

    records = []
    for faces, value, bound in ((400, 512.0, ">="), (200, 150.0, None), (100, 40.0, None)):
        r = views_record("a", BASE, target=faces, faces=faces)
        r["screen"] = {"switch_px": {"value": value, "bound": bound},
                       "switch_px_rms": {"value": value, "bound": bound}}
        records.append(r)
    html = _screen_sizes(records, Inline(), "m")
    rows = [re.sub(r"<[^>]+>", "|", row) for row in re.findall(r"<tr>.*?</tr>", html)]
    # the 100-face level switches at 40 px: at 128 and at 64 px 200 faces are needed
    assert any(row.endswith("|400:&gt;=512 200:150 100:40||200||200||") for row in rows), rows
    assert "<img" in html
    assert _screen_sizes([views_record("a", BASE)], Inline(), "m") == ""


def _screened(label, faces, value, bound=None, model="m"):
    """A record of ``faces`` faces whose switch size is ``value`` (with its bound)."""
    r = views_record(label, BASE, model=model, target=faces, faces=faces)
    r["screen"] = {"switch_px": {"value": value, "bound": bound},
                   "switch_px_rms": {"value": value, "bound": bound}}
    return r


def test_the_leaderboard_says_the_fewest_faces_at_128_px():
    records = [_screened("a", 1000, 512.0, ">="), _screened("a", 500, 130.0),
               _screened("a", 250, 90.0), _screened("b", 1000, 200.0),
               _screened("b", 500, 100.0), _screened("c", 500, 32.0, "<")]
    html = leaderboard_html(records)
    table = html[html.index("<table id='faces-at'"):]
    table = table[:table.index("</table>")]
    # a needs 500 (250 switches at 90 < 128); b needs 1000; c never gets there
    assert "<td>m</td><td>500</td><td>a</td><td>b 1000</td>" in table
    assert "Faces at 128 px" in html


def test_no_faces_at_table_without_screen_sizes():
    html = leaderboard_html([views_record("a", BASE), views_record("b", shifted(1.0))])
    assert "faces-at" not in html
