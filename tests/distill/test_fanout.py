import sys
from pathlib import Path

import pytest

from distill.experts.fanout import Job, run_jobs, summarise

sys.path.insert(0, str(Path(__file__).parent))  # spawned workers inherit sys.path
import fanout_jobs


def jobs(tmp_path):
    return [
        Job("square", fanout_jobs.square, {"x": 3}),
        Job("raises_once", fanout_jobs.fail_once, {"marker": str(tmp_path / "a")}),
        Job("crashes_once", fanout_jobs.fail_once, {"marker": str(tmp_path / "b"), "crash": True}),
        Job("broken", fanout_jobs.always_fails),
        Job("finished", fanout_jobs.square, {"x": 1}, done=True),
    ]


def check(reports):
    by_name = {r.name: r for r in reports}
    assert by_name["square"].status == "ok" and by_name["square"].result == 9
    assert by_name["raises_once"].status == "ok" and by_name["raises_once"].attempts == 2
    assert by_name["crashes_once"].status == "ok" and by_name["crashes_once"].attempts == 2
    assert by_name["broken"].status == "failed" and by_name["broken"].attempts == 3
    assert "ValueError" in by_name["broken"].error
    assert by_name["finished"].status == "skipped" and by_name["finished"].attempts == 0
    text = summarise(reports)
    assert "3 ok, 1 skipped, 1 failed" in text and "broken job" in text


def test_process_pool_retries_and_reports(tmp_path):
    check(run_jobs(jobs(tmp_path), workers=2, progress=False))


def test_ray_path_on_a_local_instance(tmp_path):
    pytest.importorskip("ray")
    import ray.cloudpickle

    ray.cloudpickle.register_pickle_by_value(fanout_jobs)  # Ray workers do not see the tests folder
    check(run_jobs(jobs(tmp_path), ray_address="local", progress=False))


def test_a_crashing_worker_costs_only_its_own_job_an_attempt(tmp_path):
    # Three slow jobs run beside two that kill their own process; with a shared process pool the
    # crashes broke the pool and every job in it lost an attempt.
    jobs = [Job(f"slow{i}", fanout_jobs.slow_square, {"x": i, "seconds": 1.5}) for i in range(3)]
    jobs += [Job("segfault", fanout_jobs.crash, {"how": "segfault"}), Job("exit", fanout_jobs.crash, {"how": "exit"})]
    reports = {r.name: r for r in run_jobs(jobs, workers=5, max_attempts=2, progress=False)}
    for i in range(3):
        slow = reports[f"slow{i}"]
        assert (slow.status, slow.attempts, slow.result) == ("ok", 1, i * i)
    assert reports["segfault"].status == "failed" and reports["segfault"].attempts == 2
    assert "killed by signal SIGSEGV" in reports["segfault"].error
    assert reports["exit"].status == "failed" and "exited with code 7" in reports["exit"].error
    table = summarise(list(reports.values()))
    assert "last error: worker process died: killed by signal SIGSEGV" in table and "3 ok, 0 skipped, 2 failed" in table


def test_a_retried_job_says_why_in_the_table(tmp_path):
    reports = run_jobs([Job("raises_once", fanout_jobs.fail_once, {"marker": str(tmp_path / "m")})], progress=False)
    assert "retried after: RuntimeError: first attempt fails" in summarise(reports)


def test_duplicate_names_are_refused():
    with pytest.raises(ValueError, match="unique"):
        run_jobs([Job("a", fanout_jobs.square, {"x": 1}), Job("a", fanout_jobs.square, {"x": 2})], progress=False)


def test_each_worker_gets_its_share_of_the_cores_not_the_whole_machine(monkeypatch):
    # The CLI sets OMP_NUM_THREADS to every core it may use; two workers inheriting that
    # oversubscribed a 2-core machine and stepped 8x slower (benchmarks/worker_threads.py).
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    jobs = [Job(f"pools{i}", fanout_jobs.thread_pools) for i in range(2)]
    for report in run_jobs(jobs, workers=2, progress=False):
        assert report.status == "ok", report.error
        assert report.result == ("1", 1)


def test_threads_per_worker_splits_the_cores():
    from foundation.cores import threads_per_worker

    assert threads_per_worker(3, cores=8) == 2
    assert threads_per_worker(4, cores=2) == 1
    assert threads_per_worker(1, cores=16) == 16
