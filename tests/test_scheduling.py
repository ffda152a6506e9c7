"""Which job a free process of the local pool takes next (bench.run.runner.next_job)."""

from collections import deque

from bench.run.jobs import Job
from bench.run.runner import next_job


def _jobs(*specs):
    return [Job(model, method, faces) for model, method, faces in specs]


def _labels(jobs):
    return [(j.model, j.method, j.target_faces) for j in jobs]


def test_the_plans_order_when_nothing_is_shared():
    jobs = _jobs(("a", "qslim", 10), ("a", "quadric", 10), ("b", "qslim", 10))
    pending = deque(jobs)
    assert next_job(pending, set(), None) == jobs[0]
    assert next_job(pending, {("a", "qslim")}, None) == jobs[1]
    assert _labels(pending) == [("b", "qslim", 10)]


def test_a_second_process_does_not_start_the_same_model_and_method():
    """The main job's order: a model's two perceptual-mt budgets side by side. The second
    process takes the next other job; the first, when free, takes the second budget."""
    jobs = _jobs(("bunny", "perceptual-mt", 1123), ("bunny", "perceptual-mt", 562),
                 ("bunny", "qslim", 1123), ("bunny", "qslim", 562))
    pending = deque(jobs)
    first = next_job(pending, set(), None)
    second = next_job(pending, {("bunny", "perceptual-mt")}, None)
    assert (first, second) == (jobs[0], jobs[2])
    # the first process is free again while the second still runs qslim
    assert next_job(pending, {("bunny", "qslim")}, ("bunny", "perceptual-mt")) == jobs[1]
    assert _labels(pending) == [("bunny", "qslim", 562)]


def test_a_process_keeps_to_its_last_group_ahead_of_the_plans_order():
    jobs = _jobs(("a", "qslim", 10), ("b", "perceptual-mt", 20), ("b", "perceptual-mt", 10))
    pending = deque(jobs)
    assert next_job(pending, set(), ("b", "perceptual-mt")) == jobs[1]
    assert next_job(pending, set(), ("b", "perceptual-mt")) == jobs[2]
    assert next_job(pending, set(), ("b", "perceptual-mt")) == jobs[0]
    assert not pending


def test_never_idle_while_jobs_wait():
    """When every waiting job's group runs elsewhere, the first is taken anyway."""
    jobs = _jobs(("a", "perceptual-mt", 20), ("a", "perceptual-mt", 10))
    pending = deque(jobs)
    assert next_job(pending, {("a", "perceptual-mt")}, None) == jobs[0]
    assert next_job(pending, {("a", "perceptual-mt")}, ("x", "y")) == jobs[1]
    assert not pending


def test_every_job_is_taken_once():
    jobs = _jobs(*[(m, meth, f) for m in ("a", "b") for meth in ("p", "q") for f in (3, 2, 1)])
    pending, taken, last = deque(jobs), [], None
    running = set()
    while pending:
        job = next_job(pending, running, last)
        taken.append(job)
        running = {(job.model, job.method)} if len(taken) % 2 else set()
        last = (job.model, job.method)
    assert sorted(_labels(taken)) == sorted(_labels(jobs)) and len(taken) == len(jobs)
