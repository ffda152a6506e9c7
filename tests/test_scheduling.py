"""Which job a free process of the local pool takes next (bench.run.runner.next_job)."""

from collections import deque

from hypothesis import given, settings
from hypothesis import strategies as st

from bench.run.jobs import Job
from bench.run.runner import Families, _families, next_job


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


# -- kernel families: one process compiles a family, the others wait or run other jobs --

KERNELS = {"qslim": (), "memoryless": ("engine",), "image-driven": ("engine", "imaging"),
           "entropy-twin": ("engine", "imaging", "canny")}


def test_the_engines_builder_starts_first_and_the_baselines_run_beside_it():
    jobs = _jobs(("a", "qslim", 9), ("a", "image-driven", 9), ("a", "memoryless", 9),
                 ("b", "memoryless", 9), ("b", "qslim", 9))
    pending, families = deque(jobs), Families(KERNELS)
    assert next_job(pending, set(), None, families, 0) == jobs[2]  # builds the engine
    # the other process: image-driven needs the engine, memoryless b the method's own
    # first warm-up; qslim needs neither
    assert next_job(pending, {("a", "memoryless")}, None, families, 1) == jobs[0]
    assert next_job(pending, {("a", "memoryless")}, None, families, 1) is None  # qslim's own
    families.left_setup(1)  # qslim a left its set-up
    assert next_job(pending, {("a", "memoryless")}, None, families, 1) == jobs[4]
    families.ended(1, left_setup=True)
    assert next_job(pending, set(), None, families, 1) is None  # all wait for the engine
    families.left_setup(0)
    assert next_job(pending, set(), ("b", "qslim"), families, 1) == jobs[1]  # builds imaging
    assert next_job(pending, {("a", "image-driven")}, None, families, 0) == jobs[3]
    assert not pending


def test_a_family_whose_job_ended_in_its_set_up_is_claimed_again():
    jobs = _jobs(("a", "memoryless", 9), ("b", "memoryless", 9))
    pending, families = deque(jobs), Families(KERNELS)
    assert next_job(pending, set(), None, families, 0) == jobs[0]
    assert next_job(pending, set(), None, families, 1) is None
    families.ended(0, left_setup=False)  # e.g. skipped, or its process died compiling
    assert next_job(pending, set(), None, families, 1) == jobs[1]
    assert families.claims == {("kernels", "engine"): 1, ("method", "memoryless"): 1}


def test_a_models_shared_work_is_built_by_one_job_before_the_others_start():
    """perceptual-mt's two budgets of a model: the second waits for the first to end
    (its MT is then in the run's cache), not merely to leave its set-up."""
    jobs = _jobs(("t", "perceptual-mt", 2), ("t", "perceptual-mt", 1), ("b", "perceptual-mt", 1))
    pending = deque(jobs)
    families = Families({"perceptual-mt": ("engine", "mt")}, {"perceptual-mt"})
    assert next_job(pending, set(), None, families, 0) == jobs[0]
    families.left_setup(0)
    assert next_job(pending, {("t", "perceptual-mt")}, None, families, 1) == jobs[2]
    families.left_setup(1)
    assert next_job(pending, set(), None, families, 1) is None  # jobs[1] waits for t's MT
    families.ended(0, left_setup=True)
    assert next_job(pending, set(), None, families, 0) == jobs[1]
    assert not pending


def test_a_models_shared_work_is_left_to_the_next_job_when_its_job_failed():
    jobs = _jobs(("t", "perceptual-mt", 2), ("t", "perceptual-mt", 1))
    pending = deque(jobs)
    families = Families({"perceptual-mt": ()}, {"perceptual-mt"})
    assert next_job(pending, set(), None, families, 0) == jobs[0]
    families.left_setup(0)
    families.ended(0, left_setup=True, failed=True)  # e.g. timed out building the MT
    assert next_job(pending, set(), None, families, 1) == jobs[1]
    assert families.claims == {("work", "t", "perceptual-mt"): 1}


def test_a_method_the_supervisor_cannot_load_needs_no_family():
    """A plug-in only the job processes find (its path set after this process loaded the
    registry) is run, not refused: its job process loads it or fails the job."""
    families = _families(_jobs(("a", "no-such-method", 9), ("a", "qslim", 9)))
    assert families.needs(Job("a", "no-such-method", 9)) == (("method", "no-such-method"),)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.sampled_from("ab"), st.sampled_from(sorted(KERNELS)),
                          st.integers(1, 3)), min_size=1, max_size=12, unique=True),
       st.lists(st.tuples(st.integers(0, 2), st.booleans()), max_size=60))
def test_no_family_is_compiled_by_two_processes_and_every_job_runs_once(specs, events):
    """Three processes take jobs and leave their set-ups (built or not) in an arbitrary
    order: no family is ever claimed by two, a job starts only when none of its unbuilt
    families is claimed by another process, and every job runs exactly once."""
    jobs = _jobs(*specs)
    pending, families = deque(jobs), Families(KERNELS, {"image-driven"})
    busy: dict[int, object] = {}
    taken = []
    events = list(events) + [(p, True) for _ in range(len(jobs) + 1) for p in range(3)]
    for owner, built in events:
        if owner in busy:  # its job leaves its set-up (and, here, ends)
            del busy[owner]
            if built:
                families.left_setup(owner)
            families.ended(owner, left_setup=built, failed=not built)
            continue
        if not pending:
            continue
        job = next_job(pending, set(), None, families, owner)
        if job is None:
            assert busy, "a job waits though no process compiles anything"
            continue
        others = {f for f, o in families.claims.items() if o != owner}
        assert not others & set(families.needs(job))
        busy[owner] = job
        taken.append(job)
        claimed = list(families.claims)
        assert len(claimed) == len(set(claimed))
        assert not families.built & set(claimed)
    assert sorted(_labels(taken)) == sorted(_labels(jobs))


def test_a_long_set_up_is_said_on_the_progress_bar():
    """A job warming up for longer than SETUP_NOTE_AFTER (a first run, compiling) is
    named; one in its method, or warming up briefly, is not."""
    import time
    from types import SimpleNamespace

    from bench.run.runner import SETUP_NOTE_AFTER, setup_note

    now = time.monotonic()
    job = Job("bunny", "memoryless", 1123)
    compiling = SimpleNamespace(job=job, phase="setup", started=now - SETUP_NOTE_AFTER - 5)
    running = SimpleNamespace(job=job, phase="method", started=now - 100)
    brief = SimpleNamespace(job=job, phase="setup", started=now)
    idle = SimpleNamespace(job=None, phase="setup", started=now - 100)
    assert setup_note([None, idle, running, brief]) is None
    text = setup_note([running, compiling])
    assert text.startswith("bunny memoryless 1123: setting up for 15 s")
