import runpy
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_tour_runs(clip_library, capsys):
    runpy.run_path(str(EXAMPLES / "tour_of_the_tasks.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "velocity_control" in out and "normalised reward" in out


def test_new_task_example_trains_on_a_decoder_file(clip_library, tmp_path, capsys):
    import numpy as np
    import torch

    import tasks
    from hierarchy import DecoderSpec, LatentDecoder
    from tasks.observables import DECODER, PROPRIOCEPTION

    source = EXAMPLES / "new_task.py"
    assert len(source.read_text().splitlines()) < 135
    torch.manual_seed(0)
    spec = DecoderSpec({k: PROPRIOCEPTION[k] for k in DECODER}, latent_size=4, hidden_layers=(16,))
    decoder = LatentDecoder(spec, np.zeros(spec.observation_size), np.ones(spec.observation_size))
    path = decoder.save(tmp_path / "decoder.safetensors")
    example = runpy.run_path(str(source), run_name="example")
    assert "raise_hand" in tasks.task_names()
    out_dir = tmp_path / "run"
    argv = ["--decoder", str(path), "--out", str(out_dir), "--steps", "64", "--n-envs", "2", "--hidden", "16"]
    score = example["main"](argv)  # two environments in spawned worker processes: they must find the task
    out = capsys.readouterr().out
    assert np.isfinite(score) and f"after 64 steps {score:.3f}" in out
    assert "untrained 0." in out and "--steps 32768" in out  # the baseline and how to train longer
    assert (out_dir / "policy.safetensors").is_file() and (out_dir / "raise_hand.rrd").is_file()
    tasks.REGISTRY.pop("raise_hand")  # leave the registry as the other tests expect it
