import runpy
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_tour_runs(clip_library, capsys):
    runpy.run_path(str(EXAMPLES / "tour_of_the_tasks.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "velocity_control" in out and "normalised reward" in out
