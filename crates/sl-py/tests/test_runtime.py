"""Zero-copy input, GIL release and the thread pool."""

import os
import threading
import time

import numpy as np
import pytest

import sldepth


def test_c_contiguous_float32_is_borrowed(three_planes):
    depth = three_planes[0]
    assert depth.flags.c_contiguous and depth.dtype == np.float32
    assert sldepth.input_is_borrowed(depth)
    assert not sldepth.input_is_borrowed(depth.astype(np.float64))
    assert not sldepth.input_is_borrowed(depth[:, ::2])
    assert not sldepth.input_is_borrowed(np.full((4, 4), 1000, np.uint16), depth_scale=1000)


def test_outputs_own_their_memory(kinect, three_planes):
    depth = three_planes[0]
    out = sldepth.filter(depth, kinect)
    assert out.flags.c_contiguous and out.flags.writeable
    assert not np.shares_memory(out, depth)


def test_gil_is_released_during_computation(kinect):
    depth, _, _ = sldepth.simulate("figure-walls", seed=2)
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0)

    sldepth.set_num_threads(1)
    try:
        t = threading.Thread(target=count)
        t.start()
        time.sleep(0.01)
        before = len(ticks)
        start = time.perf_counter()
        calls = 0
        while time.perf_counter() - start < 0.5:
            sldepth.filter(depth, kinect, radius=8)  # long enough to be preempted
            calls += 1
        during = len(ticks) - before
        stop.set()
        t.join()
    finally:
        sldepth.set_num_threads(None)
    # The counting thread kept running while the filter held no GIL.
    assert calls > 0 and during > 10 * calls


def test_set_num_threads():
    sldepth.set_num_threads(1)
    assert sldepth.get_num_threads() == 1
    sldepth.set_num_threads(2)
    assert sldepth.get_num_threads() == 2
    sldepth.set_num_threads(None)
    assert sldepth.get_num_threads() >= 1


def _in_a_new_thread(fn):
    out = []
    t = threading.Thread(target=lambda: out.append(fn()))
    t.start()
    t.join()
    return out[0]


def test_a_call_computes_on_the_calling_thread():
    # Shared pools' workers are named sldepth-<i>; Python's threads have no Rust name. A Python
    # thread is worker 0 of a pool of its own, sized at its first call, so calls run in place
    # (no hand-over to a worker and back) at every thread count; a call with another count than
    # the thread's first goes to a shared pool of that count.
    name = sldepth._sldepth._compute_thread_name

    def first_then_other(first, other):
        sldepth.set_num_threads(first)
        a = name()
        sldepth.set_num_threads(other)
        b = name()
        sldepth.set_num_threads(first)
        return a, b, name()

    try:
        seen = {n: _in_a_new_thread(lambda n=n: first_then_other(n, 3)) for n in (1, 2, None)}
    finally:
        sldepth.set_num_threads(None)
    for n, (first, other, again) in seen.items():
        assert first is None and again is None, (n, seen)
        assert other.startswith("sldepth-"), (n, seen)


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads in /proc")
def test_own_pools_do_not_start_threads_without_bound(three_planes):
    # Own pools may have at most eight spawned workers per core alive at once: with 4 * cores + 1
    # threads per call (4 * cores spawned workers per own pool) at most two of four Python
    # threads computing at once get one; the others use the shared pool. Results are the same
    # either way, and the workers end with their threads.
    cam = sldepth.Camera(64, 48, 60.0, 60.0, 32.0, 24.0)
    small = three_planes[0][:48, :64].copy()
    ref = sldepth.filter(small, cam)
    k = 4 * os.cpu_count() + 1
    n = 4
    barrier = threading.Barrier(n + 1)
    names, same, tasks = [], [], []

    def work():
        names.append(sldepth._sldepth._compute_thread_name())
        same.append(np.array_equal(sldepth.filter(small, cam), ref))
        barrier.wait()  # all alive at once
        barrier.wait()

    sldepth.set_num_threads(k)
    try:
        before = len(os.listdir("/proc/self/task"))
        threads = [threading.Thread(target=work) for _ in range(n)]
        for t in threads:
            t.start()
        barrier.wait()
        tasks.append(len(os.listdir("/proc/self/task")))
        barrier.wait()
        for t in threads:
            t.join()
    finally:
        sldepth.set_num_threads(None)
    assert all(same) and len(same) == n
    shared = [x for x in names if x is not None and x.startswith("sldepth-")]
    assert len(shared) >= n - 2, names
    # The n Python threads, at most 8 * cores spawned workers of own pools and the shared pool
    # of k threads (built by the first call that falls back to it).
    assert tasks[0] - before <= n + 8 * os.cpu_count() + k, (before, tasks)


def test_one_thread_pools_are_bounded(three_planes):
    # Each thread that computes with one thread keeps a pool rayon cannot free; past a fixed
    # number of threads the later ones share one pool (a worker named sldepth-0), with the same
    # results.
    cam = sldepth.Camera(64, 48, 60.0, 60.0, 32.0, 24.0)
    small = three_planes[0][:48, :64].copy()
    ref = sldepth.filter(small, cam)
    names, same = [], []

    def work():
        names.append(sldepth._sldepth._compute_thread_name())
        same.append(np.array_equal(sldepth.filter(small, cam), ref))

    sldepth.set_num_threads(1)
    try:
        for _ in range(300):
            t = threading.Thread(target=work)
            t.start()
            t.join()
    finally:
        sldepth.set_num_threads(None)
    assert all(same) and len(same) == 300
    assert set(names) <= {None, "sldepth-0"} and names[-1] == "sldepth-0", set(names)


def test_two_python_threads_share_the_pool(kinect, three_planes):
    depth = three_planes[0]
    ref = sldepth.filter(depth, kinect)
    results = [None, None]

    def work(i):
        results[i] = sldepth.filter(depth, kinect)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(np.array_equal(r, ref) for r in results)


def test_python_threads_call_everything_at_once(kinect):
    # Every call runs on the pool, and a worker waiting for a parallel part of one call may run
    # another thread's call on the same thread: results must not depend on that. (A per-thread
    # plane-extractor cache once failed here with "already borrowed".) Three threads, on the
    # global pool and on pools of one and two threads.
    depth, _, _ = sldepth.simulate("figure-walls", seed=3)
    other, _, _ = sldepth.simulate("figure-walls", seed=4)
    ref_filter = sldepth.filter(depth, kinect)
    ref_labels, ref_planes = sldepth.extract_planes(depth, kinect)
    ref_motion = sldepth.motion(depth, other, kinect).matrix
    errors = []

    def work():
        try:
            for i in range(20):
                labels, planes = sldepth.extract_planes(depth, kinect)
                assert np.array_equal(labels, ref_labels)
                assert [p.pixels for p in planes] == [p.pixels for p in ref_planes]
                assert np.array_equal(sldepth.filter(depth, kinect), ref_filter)
                if i % 5 == 0:
                    m = sldepth.motion(depth, other, kinect).matrix
                    assert (m is None and ref_motion is None) or np.array_equal(m, ref_motion)
        except BaseException as e:  # noqa: BLE001 - a Rust panic is a BaseException
            errors.append(repr(e))

    try:
        for n in (None, 1, 2):
            sldepth.set_num_threads(n)
            threads = [threading.Thread(target=work) for _ in range(3)]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            assert not errors, f"{n} threads: {errors[0]}"
    finally:
        sldepth.set_num_threads(None)


_SHARED_OBJECT_CALLS = r"""
import os, sys, threading, time
import numpy as np
import sldepth

cam = sldepth.Camera.preset("kinect-v1")
z = sldepth.simulate("three-planes", seed=3)[0]
vol = sldepth.TsdfVolume()
tracker = sldepth.Tracker(cam)
errors = []
threads = int(sys.argv[1])

def calls(k, n):
    for j in range(n):
        p = np.eye(4)
        p[0, 3] = 0.01 * k + 0.001 * j
        vol.integrate(z, cam, p)
        if j % 2 == 0:
            tracker.track(z)
            vol.extract_mesh()

def work(k, ready):
    try:
        if ready is not None:
            calls(k, 1)  # the thread's first call: its own pool takes the count in force
            ready.wait()
            ready.wait()  # now the count differs: calls go through the shared pool
        calls(k, 4)
    except BaseException as e:  # a Rust panic is a BaseException
        errors.append(repr(e))

ready = threading.Barrier(threads + 1) if threads == 2 else None
ts = [threading.Thread(target=work, args=(k, ready), daemon=True) for k in range(threads)]
for t in ts:
    t.start()
if ready is not None:
    ready.wait()
    sldepth.set_num_threads(3)
    ready.wait()
start = time.time()
for t in ts:
    t.join(timeout=max(0.1, 100 - (time.time() - start)))
print("hung" if any(t.is_alive() for t in ts) else "done", errors, flush=True)
os._exit(0)
"""


@pytest.mark.parametrize("threads", [2, 20])
def test_threads_sharing_one_volume_and_tracker_never_deadlock(tmp_path, threads):
    # A call used to take the object's lock inside the pool: a worker waiting for its parallel
    # pieces ran another thread's queued call on the same object, which then waited for the lock
    # its own thread held, for ever. Reached through the shared pools: two threads after
    # `set_num_threads` changed the count, or more threads than own pools may start (8 per core).
    # In a subprocess, so that a regression fails here instead of hanging the suite.
    import subprocess
    import sys

    script = tmp_path / "shared.py"
    script.write_text(_SHARED_OBJECT_CALLS)
    out = subprocess.run(
        [sys.executable, str(script), str(threads)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "done []", out.stdout + out.stderr


def test_the_type_stubs_match_the_module():
    # The .pyi shipped in the wheel is what IDEs and type checkers see: every name it declares
    # exists, a stub @property is a data descriptor at runtime and a stub method is callable
    # (a stray @property once turned TsdfVolume.raycast into an attribute for type checkers),
    # and every public name of the module is declared.
    import ast
    import inspect
    import types
    from pathlib import Path

    stub = Path(sldepth.__file__).with_name("__init__.pyi")
    tree = ast.parse(stub.read_text())
    declared = set()
    descriptors = (property, types.GetSetDescriptorType, types.MemberDescriptorType)
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            declared.add(node.name)
            assert hasattr(sldepth, node.name), f"stub declares {node.name}, module has none"
        if not isinstance(node, ast.ClassDef):
            continue
        cls = getattr(sldepth, node.name)
        for item in node.body:
            if not isinstance(item, ast.FunctionDef) or item.name.startswith("__"):
                continue
            where = f"{node.name}.{item.name}"
            assert hasattr(cls, item.name), f"stub declares {where}, runtime has none"
            attr = inspect.getattr_static(cls, item.name)
            decorators = {d.id for d in item.decorator_list if isinstance(d, ast.Name)}
            if "property" in decorators:
                assert isinstance(attr, descriptors), f"{where} is a property in the stub only"
            else:
                assert not isinstance(attr, descriptors) and callable(getattr(cls, item.name)), (
                    f"{where} is a method in the stub but an attribute at runtime"
                )
    public = {
        n
        for n in dir(sldepth)
        if not n.startswith("_")
        and callable(getattr(sldepth, n))
        and not isinstance(getattr(sldepth, n), types.ModuleType)
    }
    assert public <= declared | {"SlDepthError", "SlDepthIOError"}, sorted(public - declared)


def test_the_readme_examples_run_as_written(tmp_path, monkeypatch):
    # Every ```python block of the repository README and of crates/sl-py/README.md, run in a
    # scratch directory (the examples write files there).
    from pathlib import Path

    here = Path(__file__).resolve()
    readmes = [here.parents[3] / "README.md", here.parents[1] / "README.md"]
    blocks = []
    for readme in readmes:
        if not readme.is_file():
            pytest.skip(f"{readme} is not here (the tests run outside the repository)")
        text = readme.read_text()
        parts = text.split("```python\n")[1:]
        blocks += [(readme.name, p.split("```")[0]) for p in parts]
    assert len(blocks) >= 3, blocks
    monkeypatch.chdir(tmp_path)
    for name, code in blocks:
        exec(compile(code, f"<{name}>", "exec"), {})
