"""One command on an offline GPU node: assemble the staged site, record the versions, run the checks by value.

    python3 tools/device/run.py --staged DIR --out results/ [--budget-seconds 540] [--device cuda] [--only STAGE ...]
    python tools/device/run.py --site .venv/lib/python3.11/site-packages --out /tmp/out --rehearsal  # no GPU

Assembly joins and verifies the staged site's parts (``tools/device/parts.py join``), extracts
them to /tmp/mh-site (kept for a next command on the same node) and copies the Warp kernel
cache packed with them (``warp-kernel-cache/``, or ``--kernels DIR``) to /tmp/mh-warp-cache
(``WARP_CACHE_PATH``); ``--site`` names an extracted site instead. Then
each stage (versions, then the checks in order of value: parity, speed, ppo, expert) runs in a
process group of its own with ``PYTHONPATH=<site>:<repo>``, so one that crashes or hangs costs
only itself. A check gets a share of the time left when it starts (what earlier ones leave
unused goes on); at its budget its group gets SIGTERM, then SIGKILL, and it is recorded as
``timeout`` with whatever result it had written. results.json is rewritten (atomically) after
each stage and log.txt grows line by line, so a lease that ends early still returns what
finished. Only this process writes to ``--out``; it needs the standard library only.
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tarfile
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository, for foundation (run as a script)

from foundation.atomic import write_text

REPO = Path(__file__).resolve().parents[2]
SITE, WARP_CACHE = Path("/tmp/mh-site"), Path("/tmp/mh-warp-cache")
SHARES = {"parity": 0.12, "speed": 0.25, "ppo": 0.13, "expert": 0.5}
"""The checks in order of value, each with its weight in sharing the time left."""
VERSIONS_SECONDS, MARGIN_SECONDS, MIN_STAGE_SECONDS, KILL_GRACE_SECONDS = 120.0, 15.0, 20.0, 10.0
LOG_LIMIT_BYTES = 12 * 2**20
WALK = "SYN_walk_slow-0-182"
SIZES = {
    "device": {
        "states": 256, "worlds": [16384, 4096, 1024, 256, 64, 16, 4, 1], "steps": 100, "cpu_steps": 1000,
        "steps_per_env": 32, "ppo_worlds": 4096, "ppo_updates": 8, "expert_worlds": 1024, "expert_seconds": 300,
        "flags": [],
    },
    "rehearsal": {
        "states": 8, "worlds": [2, 1], "steps": 2, "cpu_steps": 20,
        "steps_per_env": 16, "ppo_worlds": 8, "ppo_updates": 3, "expert_worlds": 8, "expert_seconds": 20,
        "flags": ["--minibatch-size", "64", "--epochs", "2", "--hidden-layers", "32", "32"],
    },
}  # fmt: skip
"""Sizes per kind of run; ``speed`` goes from the most telling batch down, so a budget running out loses least."""


# The parent: records, stages as processes, assembly ---------------------------------------


def write_json(path: Path, value) -> None:
    """Writes ``value`` as JSON at once (a reader never sees half a file); what JSON lacks becomes text."""
    write_text(path, json.dumps(value, indent=2, default=str) + "\n")


def read_json(path: Path):
    """The JSON in ``path``; None if it is missing or unfinished."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


class Recorder:
    """results.json (rewritten with each entry) and log.txt (appended line by line, echoed) under ``out``."""

    def __init__(self, out: Path) -> None:
        out.mkdir(parents=True, exist_ok=True)
        self.out, self.results, self.logged, self.lock = out, [], 0, threading.Lock()
        self.log = (out / "log.txt").open("a", encoding="utf-8")

    def line(self, text: str) -> None:
        """Prints a line and appends it to log.txt (up to LOG_LIMIT_BYTES)."""
        with self.lock:
            print(text, flush=True)
            if self.logged < LOG_LIMIT_BYTES:
                self.log.write(text + "\n")
                self.log.flush()
                self.logged += len(text) + 1

    def record(self, entry: dict) -> None:
        """Adds an entry and rewrites results.json."""
        self.results.append(entry)
        write_json(self.out / "results.json", self.results)


def run_stage(name: str, command: list[str], budget: float, env: dict, recorder: Recorder, result: Path) -> dict:
    """Runs a stage's command in its own process group for at most ``budget`` s; records how it went.

    The command may write its result (JSON) to ``result`` as often as it likes: what is there when
    it ends, or is stopped, is recorded.
    """
    result.unlink(missing_ok=True)
    recorder.line(f"=== {name} (budget {budget:.0f} s): {' '.join(command)}")
    started, tail, status = time.monotonic(), collections.deque(maxlen=40), "ok"
    process = subprocess.Popen(
        command, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True
    )

    def pump() -> None:
        for raw in process.stdout:  # type: ignore[union-attr]
            tail.append(raw.decode(errors="replace").rstrip())
            recorder.line(f"[{name}] {tail[-1]}")

    reader = threading.Thread(target=pump, daemon=True)
    reader.start()
    try:
        process.wait(timeout=budget)
    except subprocess.TimeoutExpired:
        status = "timeout"
    except BaseException:  # this process was told to stop: so is the stage, and it is recorded
        status = "interrupted"
        raise
    finally:
        if status != "ok":
            stop(process)
        reader.join(timeout=5)
        status = "failed" if status == "ok" and process.returncode != 0 else status
        entry = {"stage": name, "status": status, "seconds": round(time.monotonic() - started, 1)}
        entry.update(budget_seconds=round(budget, 1), returncode=process.returncode, result=read_json(result))
        result.unlink(missing_ok=True)
        if status != "ok":
            entry["output_tail"] = list(tail)
        recorder.record(entry)
        recorder.line(f"=== {name}: {status} after {entry['seconds']} s")
    return entry


def stop(process: subprocess.Popen) -> None:
    """SIGTERM to the stage's process group (a trainer saves and stops), SIGKILL after a grace period."""
    try:
        os.killpg(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=KILL_GRACE_SECONDS)
        finally:
            os.killpg(process.pid, signal.SIGKILL)  # the stage if it is still there, and what it left behind
    except (ProcessLookupError, subprocess.TimeoutExpired):
        pass
    process.wait()


Command = Callable[[float, Path], list[str]]


def run_stages(plan: list[tuple[str, float, Command]], deadline: float, env: dict, recorder: Recorder) -> None:
    """Runs each ``(name, share, command)`` in turn with its share of the time left before ``deadline``."""
    for index, (name, share, command) in enumerate(plan):
        left = deadline - time.monotonic() - MARGIN_SECONDS
        budget = left * share / sum(later for _, later, _ in plan[index:])
        if budget < MIN_STAGE_SECONDS:
            recorder.record({"stage": name, "status": "skipped", "reason": f"{max(left, 0):.0f} s left"})
            continue
        result = Path(tempfile.gettempdir()) / f"mh-stage-{os.getpid()}-{name}.json"
        run_stage(name, command(budget, result), budget, env, recorder, result)


def find(root: Path, name: str) -> Path | None:
    """``root/name`` or ``root/*/name``: where the staging put it."""
    return next((p for p in [root / name, *sorted(root.glob(f"*/{name}"))] if p.exists()), None)


def extract_site(manifest: Path, parts: list[str] | None) -> Path:
    """Joins, verifies and extracts the staged site into /tmp/mh-site (once per manifest); its root."""
    digest, marker = hashlib.sha256(manifest.read_bytes()).hexdigest(), SITE / ".assembled-from"
    if not (marker.is_file() and marker.read_text() == digest):
        archive = Path(tempfile.gettempdir()) / "mh-site.tar.xz"
        join = [sys.executable, str(REPO / "tools/device/parts.py"), "join", "--manifest", str(manifest)]
        join += ["--parts", *parts] if parts else []  # parts that came in several calls
        joined = subprocess.run([*join, "--out", str(archive)], capture_output=True, text=True)
        if joined.returncode != 0:
            raise RuntimeError(f"parts.py join exited {joined.returncode}: {(joined.stdout + joined.stderr)[-2000:]}")
        shutil.rmtree(SITE, ignore_errors=True)
        SITE.mkdir(parents=True)
        with tarfile.open(archive) as tar:
            tar.extractall(SITE, filter="tar")
        archive.unlink()
        marker.write_text(digest)
    site = SITE
    while len(entries := [p for p in site.iterdir() if p != marker]) == 1 and entries[0].is_dir():
        site = entries[0]  # the archive holds one folder (site-packages/): that is the site
    return site


def kernel_cache(kernels: Path, env: dict) -> Path:
    """Copies the staged kernels to /tmp/mh-warp-cache/<warp version> (Warp appends its version to the path)."""
    asked = [sys.executable, "-c", "import warp.config; print(warp.config.version)"]
    version = subprocess.run(asked, env=env, capture_output=True, text=True, check=True).stdout.strip()
    if not (WARP_CACHE / version).is_dir():  # a copy: Warp writes there, the staged folder may be read-only
        source = kernels / version if (kernels / version).is_dir() else kernels
        shutil.copytree(source, WARP_CACHE / version, ignore=shutil.ignore_patterns("kernels.json"))
    return WARP_CACHE


def count_modules(cache: str | None) -> int | None:
    """Compiled Warp modules in a cache folder."""
    return sum(1 for _ in Path(cache).glob("wp_*")) if cache and Path(cache).is_dir() else None


def git_commit() -> str | None:
    try:
        asked = ["git", "rev-parse", "HEAD"]
        return subprocess.run(asked, cwd=REPO, capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None


def stage_plan(args: argparse.Namespace) -> list[tuple[str, float, Command]]:
    """The checks asked for (``--only``), each with its share and its command line."""
    size, tiny = SIZES["rehearsal" if args.rehearsal else "device"], ["--rehearsal"] if args.rehearsal else []

    def own(name: str) -> Command:  # a stage function of this file, in a process of its own
        common = [sys.executable, __file__, "--stage", name, "--device", args.device, *tiny]
        return lambda budget, result: [*common, "--result", str(result), "--budget-seconds", f"{budget:.0f}"]

    def speed(budget: float, result: Path) -> list[str]:  # the benchmark itself; it writes after each batch
        sizes = ["--worlds", *map(str, size["worlds"]), "--steps", str(size["steps"])]
        return [sys.executable, "benchmarks/warp_speed.py", "--device", args.device, *sizes, "--cpu-steps",
                str(size["cpu_steps"]), "--physics", "--no-graph", "--json", str(result)]  # fmt: skip

    commands = {"parity": own("parity"), "speed": speed, "ppo": own("ppo"), "expert": own("expert")}
    return [(name, share, commands[name]) for name, share in SHARES.items() if not args.only or name in args.only]


def main_parent(args: argparse.Namespace) -> int:
    """Assembles, records the versions, runs the checks; 0 when every stage was ``ok``."""
    started = time.monotonic()
    deadline, recorder = started + args.budget_seconds, Recorder(Path(args.out))
    signal.signal(signal.SIGTERM, lambda number, frame: sys.exit(128 + number))  # the running stage stops too
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "MOCAP_HIERARCHY_CACHE": "/tmp/mh-cache"}
    staged = Path(args.staged) if args.staged else None
    try:
        manifest = find(staged, "manifest.json") if staged else None
        if not args.site and manifest is None:
            raise FileNotFoundError(f"no manifest.json in {staged} or a folder in it")
        site = Path(args.site).resolve() if args.site else extract_site(manifest, args.parts)  # type: ignore[arg-type]
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), str(REPO), os.environ.get("PYTHONPATH")]))
        packed = site / "warp-kernel-cache"  # stage.py packs the kernel cache into the site's archive
        kernels = Path(args.kernels) if args.kernels else packed if packed.is_dir() else None
        if kernels:
            env["WARP_CACHE_PATH"] = str(kernel_cache(kernels, env))
    except Exception as error:  # nothing runs without a site: say why and stop
        recorder.record({"stage": "assemble", "status": "failed", "error": f"{type(error).__name__}: {error}"})
        return 1
    seconds, cache = round(time.monotonic() - started, 1), env.get("WARP_CACHE_PATH", "Warp's default")
    recorder.record({"stage": "assemble", "status": "ok", "seconds": seconds, "site": str(site), "warp_cache": cache})

    result = Path(tempfile.gettempdir()) / f"mh-stage-{os.getpid()}-versions.json"
    command = [sys.executable, __file__, "--stage", "versions", "--result", str(result), "--device", args.device]
    budget = max(min(VERSIONS_SECONDS, deadline - time.monotonic() - MARGIN_SECONDS), 5.0)
    versions = run_stage("versions", command, budget, env, recorder, result)["result"] or {}
    write_json(recorder.out / "versions.json", {**versions, "commit": args.commit or git_commit()})

    run_stages(stage_plan(args), deadline, env, recorder)
    statuses = {entry["stage"]: entry["status"] for entry in recorder.results}
    summary = {"stage": "summary", "seconds": round(time.monotonic() - started, 1), "statuses": statuses}
    summary["warp_modules_before"] = versions.get("warp_kernel_modules")  # more after: compiled on this machine
    summary["warp_modules_after"] = count_modules(versions.get("warp_kernel_cache"))
    recorder.record(summary)
    return 0 if all(status == "ok" for status in statuses.values()) else 1


# The stages, each in a process of its own (PYTHONPATH=<site>:<repo>) ------------------------

Report = Callable[[dict], None]


def synchronize() -> None:
    import torch

    if torch.cuda.is_available():
        torch.cuda.synchronize()


def stage_versions(args: argparse.Namespace, report: Report) -> bool:
    """Python, each library as found on the path (version and folder), the device, Warp's kernel cache."""
    import importlib
    import importlib.metadata

    found: dict = {"python": sys.version.split()[0], "paths": {}}
    for module, package in (
        ("torch", "torch"), ("numpy", "numpy"), ("warp", "warp-lang"), ("mujoco", "mujoco"),
        ("mujoco_warp", "mujoco-warp"), ("rsl_rl", "rsl-rl-lib"), ("tensordict", "tensordict"),
        ("dm_control", "dm-control"), ("gymnasium", "gymnasium"), ("stable_baselines3", "stable-baselines3"),
    ):  # fmt: skip
        try:
            loaded = importlib.import_module(module)
            found["paths"][module] = str(Path(loaded.__file__).parent)
            found[module] = getattr(loaded, "__version__", None) or importlib.metadata.version(package)
        except Exception as error:  # missing or broken: recorded, the others go on
            found[module] = f"unavailable: {type(error).__name__}: {error}"
    import torch
    import warp

    found["torch_cuda"] = torch.version.cuda
    if torch.cuda.is_available():
        properties = torch.cuda.get_device_properties(0)
        found.update(device=properties.name, capability=f"sm_{properties.major}{properties.minor}")
        found["device_memory_gib"] = round(properties.total_memory / 2**30, 1)
    warp.init()
    found["warp_cuda_devices"] = [str(device) for device in warp.get_cuda_devices()]
    found["warp_kernel_cache"] = warp.config.kernel_cache_dir
    found["warp_kernel_modules"] = count_modules(warp.config.kernel_cache_dir)
    report(found)
    return True


def parity_test_module():
    """tests/tasks/test_batched_tracking.py (rollouts, loading, tolerances, ``assert_close``), imported by path.

    It needs pytest only to declare fixtures: without pytest (the device's site), a stand-in has the two names.
    """
    import importlib.util
    import types

    try:
        import pytest  # noqa: F401
    except ImportError:
        stand_in = types.ModuleType("pytest")
        stand_in.importorskip = lambda name, **_: importlib.import_module(name)  # type: ignore[attr-defined]
        stand_in.fixture = lambda *a, **_: a[0] if a and callable(a[0]) else (lambda f: f)  # type: ignore[attr-defined]
        sys.modules["pytest"] = stand_in
    spec = importlib.util.spec_from_file_location("batched_parity", REPO / "tests/tasks/test_batched_tracking.py")
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


def observations_check(test, expected: list[dict], actual: dict, rows: list[int]) -> dict:
    """The test's ``assert_close`` (world ``rows[i]`` against ``expected[i]``): the 5 worst errors, or its complaint."""
    try:
        worst = test.assert_close(expected, {k: v.cpu() for k, v in actual.items()}, test.EVERY_OBSERVABLE, rows)
        return {"passed": True, "worst": dict(sorted(worst.items(), key=lambda item: -item[1])[:5])}
    except AssertionError as error:  # names the 3 worst observables and by how much
        return {"passed": False, "worst": str(error)}


def compare_step(test, snapshots: list[dict], stepped) -> dict:
    """One batched step from the snapshots' states against the CPU env's step, checked as the parity test does."""
    import numpy as np

    observation, reward, terminated, truncated, ends = stepped
    alive = [i for i, s in enumerate(snapshots) if not (s["terminated"] or s["truncated"])]
    ended = [i for i, s in enumerate(snapshots) if s["summary"] is not None]
    flags = [(terminated, "terminated"), (truncated, "truncated")]
    scores = ("normalized_episode_length", "normalized_episode_reward", "episode_return")
    check = {
        "observations": observations_check(test, [snapshots[i]["observation"] for i in alive], observation, alive),
        "reward_max_error": float(np.max(np.abs(reward.double().cpu().numpy() - [s["reward"] for s in snapshots]))),
        "flag_mismatches": sum(int(np.sum(f.cpu().numpy() != [s[name] for s in snapshots])) for f, name in flags)
        + sum(not bool(ends.done[i]) for i in ended),
        "episode_ends": len(ended),
        "score_max_error": max(
            (abs(float(getattr(ends, n)[i]) - snapshots[i]["summary"][n]) for i in ended for n in scores), default=0.0
        ),
    }
    check["passed"] = bool(
        check["observations"]["passed"] and check["flag_mismatches"] == 0
        and check["reward_max_error"] < test.REWARD_TOLERANCE and check["score_max_error"] <= 1e-5
    )  # fmt: skip
    return check


def stage_parity(args: argparse.Namespace, report: Report) -> bool:
    """The parity test on ``--device``: from states of CPU rollouts, one step of both engines; then resets."""
    import numpy as np
    import torch

    from tasks.clips.sources import ensure_synthetic_library
    from tasks.tracking.batched import BatchedTrackingEnv
    from tasks.tracking.env import ClipTrackingEnv, TrackingConfig

    test = parity_test_module()
    clips = str(ensure_synthetic_library(progress=False))
    config = TrackingConfig(snippets=test.SNIPPETS, clips=clips, observables=test.EVERY_OBSERVABLE)
    count = SIZES["rehearsal" if args.rehearsal else "device"]["states"]
    snapshots = test.rollout_snapshots(config, count=count, seed=1)
    env = BatchedTrackingEnv(config, num_worlds=len(snapshots), device=args.device, seed=0)
    env.reset()
    rows, actions = list(range(len(snapshots))), torch.as_tensor(np.stack([s["action"] for s in snapshots]))
    result: dict = {"device": str(env.device), "states": len(snapshots), "checks": {}}
    result["states_with_contacts"] = sum(int(s["contacts"] > 0) for s in snapshots)
    result["tolerances"] = {"observation": test.RELATIVE_TOLERANCE, "reward": test.REWARD_TOLERANCE}
    for name in ("step_1_uncaptured", "step_2_graph"):  # on CUDA step 1 captures the graph, step 2 replays it
        test.load(env, snapshots, rows)
        result["checks"][name] = compare_step(test, snapshots, env.step(actions))
        report(result)
    cpu, rng = ClipTrackingEnv(config), np.random.default_rng(4)
    snippets = rng.integers(0, len(test.SNIPPETS), len(rows))
    starts = [cpu.references[s].first_frame + int(rng.integers(cpu.start_counts[s])) for s in snippets]
    observation = env.reset(snippets=snippets, start_steps=starts)  # resets: sensors computed without actuation
    expected = [cpu.reset(options={"snippet": int(s), "start_step": int(t)})[0] for s, t in zip(snippets, starts)]  # noqa: B905
    result["checks"]["reset"] = observations_check(test, expected, observation, rows)
    result["passed"] = all(check["passed"] for check in result["checks"].values())
    report(result)
    return result["passed"]


def train_many(args: argparse.Namespace, out: Path, worlds: int, steps: int, *flags: str) -> int:
    """``mocap-hierarchy expert train-many --engine warp`` on the walk snippet, in this process; its exit status."""
    from mocap_hierarchy.cli import main

    size = SIZES["rehearsal" if args.rehearsal else "device"]
    (out / "snippets.txt").write_text(WALK + "\n")
    command = ["expert", "train-many", "--engine", "warp", "--snippets", str(out / "snippets.txt"), "--out", str(out)]
    command += ["--device", args.device, "--worlds-per-snippet", str(worlds), "--steps", str(steps)]
    return main([*command, "--steps-per-env", str(size["steps_per_env"]), *size["flags"], *flags])


def stage_ppo(args: argparse.Namespace, report: Report) -> bool:
    """PPO end to end (train-many: env + rsl_rl) in env steps/s, split into collection and updates; the env alone."""
    import torch

    from distill.experts import batched_training
    from distill.experts.config import BatchedExpertConfig
    from distill.experts.evaluation import training_task
    from tasks.tracking.batched import BatchedTrackingEnv

    size = SIZES["rehearsal" if args.rehearsal else "device"]
    worlds, per_update = size["ppo_worlds"], size["ppo_worlds"] * size["steps_per_env"]
    result: dict = {"worlds": worlds, "steps_per_update": per_update, "collect_seconds": [], "update_seconds": []}

    def timed(part: str, function):  # rates leave out the first update (warm-up)
        def wrapper(*given, **named):
            synchronize()
            started = time.perf_counter()
            value = function(*given, **named)
            synchronize()
            result[f"{part}_seconds"].append(time.perf_counter() - started)
            collect, update = sum(result["collect_seconds"][1:]), sum(result["update_seconds"][1:])
            if part == "update" and update > 0:
                steps = per_update * (len(result["update_seconds"]) - 1)
                result["training_steps_per_second"] = steps / (collect + update)
                result["collect_steps_per_second"] = steps / collect
                report(result)
            return value

        return wrapper

    batched_training._collect = timed("collect", batched_training._collect)
    batched_training._update = timed("update", batched_training._update)
    never, started, out = str(10**12), time.perf_counter(), Path(tempfile.mkdtemp(prefix="mh-ppo-"))
    flags = ["--eval-every", never, "--eval-episodes", "16", "--final-eval-episodes", "0", "--checkpoint-every", never]
    status = train_many(args, out, worlds, per_update * size["ppo_updates"], *flags)
    result["wall_seconds"] = time.perf_counter() - started
    tracking = training_task((WALK,), None, BatchedExpertConfig())  # the env alone, as trained: same task, worlds
    env = BatchedTrackingEnv(tracking, num_worlds=worlds, device=args.device, world_snippets=[0] * worlds)
    env.reset()
    steps = 4 * size["steps_per_env"]
    for index in range(3 + steps):  # an untrained policy's actions: small noise; three warm-up steps
        if index == 3:
            synchronize()
            begun = time.perf_counter()
        env.step((0.1 * torch.randn(worlds, env.action_size, device=env.device)).clamp(-1, 1))
    synchronize()
    result["env_alone_steps_per_second"] = worlds * steps / (time.perf_counter() - begun)
    report(result)
    return status == 0


def stage_expert(args: argparse.Namespace, report: Report) -> bool:
    """One walk expert for about five minutes, stopped as Ctrl-C would and resumed to finish: curve, CPU eval."""
    from distill.experts.batched_learner import CHECKPOINT_FORMAT, CHECKPOINT_VERSION, checkpoint_path
    from distill.experts.files import expert_dir_for
    from foundation.described_file import read_described

    size = SIZES["rehearsal" if args.rehearsal else "device"]
    worlds, out = size["expert_worlds"], Path(tempfile.mkdtemp(prefix="mh-expert-"))
    flags = ["--eval-every", "256", "--eval-episodes", "4", "--final-eval-episodes", "2"] if args.rehearsal else []
    expert, seconds = expert_dir_for(out, WALK), min(size["expert_seconds"], 0.65 * args.budget_seconds)
    result: dict = {"snippet": WALK, "worlds": worlds, "train_seconds_asked": round(seconds)}
    timer = threading.Timer(seconds, os.kill, (os.getpid(), signal.SIGTERM))  # a clean stop: checkpoint saved
    timer.start()
    started = time.monotonic()
    result["stopped_status"] = train_many(args, out, worlds, 10**12, *flags)  # 143: stopped by the timer
    timer.cancel()
    result["train_seconds"] = round(time.monotonic() - started, 1)
    described, _ = read_described(checkpoint_path(expert), CHECKPOINT_FORMAT, CHECKPOINT_VERSION, "checkpoint")
    result.update(steps=int(described["steps"]), evaluations=read_json(expert.evaluations))
    result["steps_per_second"] = result["steps"] / result["train_seconds"]
    report(result)
    status = train_many(args, out, worlds, result["steps"] + worlds * size["steps_per_env"], *flags)  # one update more
    result.update(finish_status=status, evaluations=read_json(expert.evaluations), done=read_json(expert.done))
    report(result)  # evaluations' "seconds" restart at the resume; done.json has cpu_evaluation
    return status == 0


STAGES = {"versions": stage_versions, "parity": stage_parity, "ppo": stage_ppo, "expert": stage_expert}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--staged", default=None, help="the staging's folder (its parts/manifest.json)")
    parser.add_argument("--site", default=None, help="an extracted site to use instead of the staged parts")
    parser.add_argument("--parts", nargs="+", default=None, help="folders holding the parts (default: the manifest's)")
    parser.add_argument(
        "--kernels", default=None, help="Warp kernel cache: kernels.py's --out (default: the packed one)"
    )
    parser.add_argument("--out", default=os.environ.get("OUT"), help="for results.json, log.txt, versions.json")
    parser.add_argument("--budget-seconds", type=float, default=540.0, help="all stages together (a stage: its own)")
    parser.add_argument("--device", default=None, help="cuda (default) or cpu (default with --rehearsal)")
    parser.add_argument("--only", nargs="+", choices=list(SHARES), default=None, help="run only these checks")
    parser.add_argument("--rehearsal", action="store_true", help="tiny sizes, to rehearse this script on a CPU")
    parser.add_argument("--commit", default=None, help="the commit to record (default: git rev-parse HEAD)")
    parser.add_argument("--stage", choices=list(STAGES), default=None, help=argparse.SUPPRESS)
    parser.add_argument("--result", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    args.device = args.device or ("cpu" if args.rehearsal else "cuda")
    if args.stage:  # one stage, in the process the parent started for it
        return 0 if STAGES[args.stage](args, lambda result: write_json(Path(args.result), result)) else 1
    if not args.out or not (args.staged or args.site):
        parser.error("give --out (or set $OUT) and --staged or --site")
    return main_parent(args)


if __name__ == "__main__":
    sys.exit(main())
