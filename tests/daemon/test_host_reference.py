"""The host reference: two fixed workloads that say how fast the measuring machine is."""

from feelium.lab.daemon import host


def test_the_reference_workloads_are_timed_in_cpu_and_grow_with_the_work(monkeypatch):
    one = host.host_reference()
    assert one["cpu_model"] and one["python_ms"] > 0 and one["numeric_ms"] > 0
    original = host._interpreted
    monkeypatch.setattr(host, "_interpreted", lambda: [original() for _ in range(4)])
    assert host.host_reference()["python_ms"] > 2.0 * one["python_ms"]  # four times the work, CPU-timed
