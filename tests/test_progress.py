"""Progress lines: a line per tenth with the time left, and the peak memory the run prints."""

import io

from pbrbench.progress import Progress, eta, peak_memory_mib


def test_lines_carry_an_eta_from_the_pace_so_far():
    assert eta(10.0, 1, 4) == "30 s" and eta(60.0, 1, 4) == "3 min 0 s" and eta(5.0, 0, 4) == "?"
    out = io.StringIO()
    with Progress(10, "jobs", bars=False, unit="job", stream=out) as p:
        for _ in range(10):
            p.update(1)
    lines = out.getvalue().splitlines()
    assert len(lines) == 10 and lines[0].startswith("pbrbench: jobs 10% (1/10, ") and "ETA " in lines[0]
    assert lines[-1].startswith("pbrbench: jobs done (10/10 jobs")


def test_peak_memory_is_this_process_in_mib():
    big = bytearray(64 << 20)   # 64 MiB touched
    big[::4096] = b"x" * len(big[::4096])
    assert 64 <= peak_memory_mib() < 64 * 1024
