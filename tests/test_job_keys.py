"""Job keys (record and image-folder names) and the identity of a method variant.

Distinct jobs have distinct keys (models with the same file stem, parameter values that
slug alike), the same job has one key in every run, and a variant is one job however its
parameters are written (a default given explicitly, ``0.50`` for ``0.5``). The gate
matches jobs by model, canonical label, budget and shading, so baselines written before
labels were canonical still match. Nothing here simplifies or renders: ``bench run`` is
called in-process with ``execute`` replaced.
"""

from __future__ import annotations

import pytest

from bench.commands.cli import build_parser
from bench.core.mesh import Mesh
from bench.io.meshio import save_mesh
from bench.records.check import compare, make_baseline
from bench.run.runner import Job, plan
from conftest import TET_FACES, TET_POSITIONS
from metrics.protocol import Protocol


@pytest.fixture
def planned(monkeypatch, tmp_path):
    """``bench run ARGS`` planned in ``tmp_path`` (with A/mesh.obj and B/mesh.obj there);
    returns the jobs handed to the runner."""
    import bench.commands.run as run_command

    for folder in ("A", "B"):
        (tmp_path / folder).mkdir()
        save_mesh(Mesh(TET_POSITIONS, TET_FACES), tmp_path / folder / "mesh.obj")
    monkeypatch.chdir(tmp_path)
    jobs = []
    monkeypatch.setattr(run_command, "execute", lambda js, *a, **k: jobs.extend(js))
    monkeypatch.setattr(run_command, "finish", lambda out, **options: 0)

    def bench_run(*args):
        jobs.clear()
        parsed = build_parser().parse_args(["run", "--faces", "2", "--out", "out", *args])
        assert run_command.run(parsed) == 0
        return list(jobs)

    return bench_run


def test_models_with_the_same_file_stem_are_two_jobs(planned, tmp_path):
    jobs = planned("--models", "A/mesh.obj,B/mesh.obj", "--methods", "qslim")
    assert [j.model for j in jobs] == ["A/mesh.obj", "B/mesh.obj"]
    assert jobs[0].key != jobs[1].key
    assert all(j.key.startswith("mesh-") for j in jobs)  # still readable
    # one file written two ways is one job
    assert len(planned("--models", "A/mesh.obj,./A/mesh.obj,A/../A/mesh.obj",
                       "--methods", "qslim")) == 1

    # --resume skips only the job whose (finished) record exists
    (tmp_path / "out" / "records").mkdir(parents=True)
    (tmp_path / "out" / "records" / f"{jobs[1].key}.json").write_text('{"status": "ok"}')
    resumed = planned("--models", "A/mesh.obj,B/mesh.obj", "--methods", "qslim", "--resume")
    assert [j.model for j in resumed] == ["A/mesh.obj"]


def test_string_values_that_slug_alike_are_different_jobs():
    values = ["a b", "a-b", "a/b", "a_b", "a--b", "a-", "a", ""]
    jobs = plan(["m"], [("image-driven", {"shading": v}) for v in values], {"m": [10]},
                Protocol())
    assert len(jobs) == len(values)
    assert len({j.key for j in jobs}) == len(values)


def test_keys_are_stable_and_plain_jobs_keep_their_old_keys():
    """The hash is of the text (not Python's per-process hash), so these are the keys in
    every run; catalog models with plain labels keep the keys records always had."""
    p = Protocol().version
    assert Job("bunny", "qslim", 1123).key == f"bunny__qslim__1123__flat-p{p}"
    assert Job("ico.obj", "qslim", 100).key == f"ico.obj__qslim__100__flat-p{p}"
    assert Job("bunny", "image-driven", 1332, {"shading": "flat"},
               Protocol("gouraud", specular=True)).key == \
        f"bunny__image-driven-shading=flat__1332__gouraud-spec-p{p}"
    assert Job("A/mesh.obj", "qslim", 100).key == f"mesh-18f1977f__qslim__100__flat-p{p}"
    assert Job("bunny", "raise", 100, {"message": "a b"}).key == \
        f"bunny__raise-message=a-b-a489f205__100__flat-p{p}"
    # protocol settings beyond the shading are part of the job too
    assert Job("bunny", "qslim", 100, {}, Protocol(resolution=256)).key != \
        Job("bunny", "qslim", 100).key


def test_a_variant_is_one_job_however_its_parameters_are_written(planned):
    jobs = planned("--models", "A/mesh.obj", "--methods",
                   "qslim,qslim[qualitythr=0.3],qslim[qualitythr=0.50],qslim[qualitythr=.5],"
                   "qslim[qualitythr=0.5],qslim[preserveboundary=no]")
    assert [j.label for j in jobs] == ["qslim", "qslim[qualitythr=0.5]"]
    assert jobs[1].params == {"qualitythr": 0.5}
    assert len({j.key for j in jobs}) == 2


def _record(label: str, d_rms: float) -> dict:
    return {"schema": 1, "status": "ok", "error": None,
            "job": {"model": "m", "method": label.split("[")[0], "params": {}, "label": label,
                    "target_faces": 100, "protocol": Protocol().as_dict()},
            "model": {"name": "m", "hash": "0" * 40, "faces": 1000},
            "method": {"name": label, "version": "1", "view_dependent": False},
            "metrics": {"d_rms": d_rms}}


def test_the_gate_matches_labels_written_before_they_were_canonical():
    """A baseline of a run that kept ``interior_views=0`` (the default) in its label
    gates the same job of a run that leaves it out; a regression is still seen."""
    entry = {"status": "ok", "method_version": "1", "protocol_version": Protocol().version}
    old = {"schema": 1, "entries": {  # as the committed baselines were written
        "m | image-driven[interior_views=0] | 100 | flat": entry | {"metrics": {"d_rms": 5.0}},
        "m | qslim[qualitythr=0.50] | 100 | flat": entry | {"metrics": {"d_rms": 7.0}}}}
    new = make_baseline([_record("image-driven", 5.0), _record("qslim[qualitythr=0.5]", 8.0)])
    marks = {(r.job, r.metric): r.mark for r in compare(old, new)}
    assert marks == {("m | image-driven | 100 | flat", "d_rms"): "same",
                     ("m | qslim[qualitythr=0.5] | 100 | flat", "d_rms"): "worse"}


def test_a_report_of_an_older_run_folder_finds_its_images(tmp_path):
    """Records written before keys carried hashes have no "key" and their images sit under
    the old key (a path's bare stem): the report still shows them."""
    import base64
    import io

    from PIL import Image

    from bench.report.page import write_report

    buf = io.BytesIO()
    Image.new("RGB", (4, 4), (200, 10, 10)).save(buf, format="PNG")
    # the key A/mesh.obj had before keys carried hashes
    folder = tmp_path / "images" / f"mesh__qslim__100__flat-p{Protocol().version}"
    folder.mkdir(parents=True)
    (folder / "view00.png").write_bytes(buf.getvalue())
    old = _record("qslim", 5.0)
    old["job"]["model"] = "A/mesh.obj"
    old["per_view"] = {"d_rms": [5.0] * 24}
    page = write_report(tmp_path, [old], single_file=True).read_text()
    assert base64.b64encode(buf.getvalue()).decode() in page
    page = write_report(tmp_path, [old]).read_text()  # images as files: a thumbnail
    key = folder.name
    assert f"<a href='images/{key}/view00.png'><img src='images/thumbs/{key}/view00.jpg'" in page
    assert (tmp_path / "images" / "thumbs" / key / "view00.jpg").is_file()
