"""The soak's verdict on resident memory and open file descriptors (tools/soak.sh).

Samples are taken at quiet moments only (soak_load.py pauses the load, waits until every
call has ended and every session has been let go, then reads /proc): the load holds nothing
in flight then, so what stays resident is what the server keeps plus what glibc keeps of
the memory a busy moment needed (its arenas and the top of its heaps). That second part
comes and goes between quiet moments: a 30-minute run without a fixed mmap threshold
switched between about 65 and 100 MB from one quiet moment to the next, to its end. A
leak, instead, raises every quiet moment, the lowest included.

So the verdict compares the lowest quiet sample of the last third of those taken after
the warm-up with the lowest of the first third: it may be higher by at most `rss_slack_kb`
(descriptors: `fd_slack`). A lowest sample can only be too low by chance, never too high,
so the swings cannot fail a run and a leak cannot hide under them.
"""


def lowest_of_thirds(values):
    """(lowest of the first third, lowest of the last third) of `values` (at least 3)."""
    third = max(1, len(values) // 3)
    return min(values[:third]), min(values[-third:])


def judge(rss_kb, fds, rss_slack_kb, fd_slack):
    """A list of failures (empty: flat) for the quiet samples after the warm-up."""
    if len(rss_kb) < 3 or len(fds) < 3:
        return ["%d quiet samples after the warm-up, 3 needed: run longer" % len(rss_kb)]
    failures = []
    rss_first, rss_last = lowest_of_thirds(rss_kb)
    if rss_last - rss_first > rss_slack_kb:
        failures.append("resident memory grew: lowest %d kB in the first third of the quiet samples, %d kB in "
                        "the last (slack %d kB)" % (rss_first, rss_last, rss_slack_kb))
    fds_first, fds_last = lowest_of_thirds(fds)
    if fds_last - fds_first > fd_slack:
        failures.append("open file descriptors grew: lowest %d in the first third of the quiet samples, %d in "
                        "the last (slack %d)" % (fds_first, fds_last, fd_slack))
    return failures
