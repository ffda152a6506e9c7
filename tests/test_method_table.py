"""scripts/method_table.py: the README's "which method for what" table from results.csv."""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "method_table.py"
HEADER = "model,method,shading,target_faces,d_rms,hausdorff_mean,seam_cracks,seconds,status\n"


def _table(tmp_path, rows: str):
    csv = tmp_path / "results.csv"
    csv.write_text(HEADER + rows)
    return subprocess.run([sys.executable, str(SCRIPT), str(csv)], capture_output=True, check=False,
                          text=True)


def test_ratios_to_the_best_of_each_cell_and_skipped_jobs_counted(tmp_path):
    out = _table(tmp_path, (
        "m,a,flat,100,10,0.002,0,1.0,ok\n"
        "m,b,flat,100,20,0.001,3,3.0,ok\n"
        "m,a,flat,50,30,0.004,0,2.0,ok\n"
        "m,b,flat,50,30,0.004,1,5.0,ok\n"
        "m,c,flat,50,,,,,skipped\n"))
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    # a: d_rms 1 and 1 (mean 1.00), Hausdorff 2 and 1 (1.50); b: 2 and 1 (1.50), 1 and 1
    assert lines[2] == "| `a` | 1.00 | 1.50 | 0 | 1.5 | 2 of 2 |"
    assert lines[3] == "| `b` | 1.50 | 1.00 | 4 | 4 | 2 of 2 |"
    assert lines[4] == "| `c` | — | — | — | — | 0 of 1 |"


def test_not_a_results_csv_is_one_line(tmp_path):
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    out = subprocess.run([sys.executable, str(SCRIPT), str(other)], capture_output=True, check=False,
                         text=True)
    assert out.returncode == 2
    assert out.stderr.startswith("method_table: error: ") and out.stderr.count("\n") == 1
    missing = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path / "none.csv")],
                             capture_output=True, text=True, check=False)
    assert missing.returncode == 2 and "No such file" in missing.stderr
