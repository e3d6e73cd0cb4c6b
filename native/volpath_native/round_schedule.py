"""How many samples per pixel the next round of a render takes.

Without a time limit a round is a fixed number of passes over the image (about a batch of paths per
thread). With one, rounds are sized as Cycles' render scheduler sizes its work
(intern/cycles/integrator/render_scheduler.cpp, get_num_samples_to_path_trace): the first round is
one sample, which measures the time per pass; later rounds take as many passes as fit a display
update interval, never more than the time left (guess_display_update_interval_in_seconds caps the
interval by the remaining render time), and the render stops once the limit is reached
(check_time_limit_reached). Short rounds on a small image would otherwise spend their time in
dispatch rather than in paths (measured at 48x48: a round of one pass costs 30 % of the
throughput on a fast scene).
"""
from __future__ import annotations

#: longest round under a time limit: how often the image and the progress bar are updated
UPDATE_INTERVAL = 1.0
#: a round under a time limit holds at most this many batches per thread, bounding the memory of
#: the results held until the round completes (64 batches of the default 16k paths: the 1M paths
#: per thread of 16 batches of 64k before session 20)
MAX_BATCHES_PER_ROUND = 64


def fixed_round_samples(samples: int, threads: int, batch: int, pixels: int) -> int:
    """Passes per round without a time limit: at least one, about a batch of paths per thread."""
    return max(1, min(samples, (threads * batch) // max(pixels, 1)))


def timed_round_samples(done: int, samples: int, elapsed: float, time_limit: float, seconds_per_pass: float,
                        threads: int, batch: int, pixels: int) -> int:
    """Passes of the next round under `time_limit` seconds (0 when the render should stop), after
    `done` passes in `elapsed` seconds; seconds_per_pass is the measured cost of one pass (0 before
    the first round)."""
    left = samples - done
    if left <= 0 or (done > 0 and elapsed >= time_limit):
        return 0
    if done == 0 or seconds_per_pass <= 0.0:
        return 1
    remaining = time_limit - elapsed
    if remaining < 0.5 * seconds_per_pass:  # the next pass would mostly run past the limit
        return 0
    interval = min(UPDATE_INTERVAL, remaining)
    by_time = max(1, int(interval / seconds_per_pass + 1e-6))  # (0.3 / 0.1 is 2.999...)
    by_memory = max(1, (MAX_BATCHES_PER_ROUND * threads * batch) // max(pixels, 1))
    return min(left, by_time, by_memory)


#: the smallest chunk of a round's tail (paths): how long the first thread done waits for the last,
#: at most, besides one chunk's fixed cost
MIN_TAIL_CHUNK = 4096


def round_chunks(n_paths: int, batch: int, threads: int) -> list:
    """[first, end) path ranges of a round's chunks, in the order the pool takes them. With several
    threads: batches while more than 2 x threads batches are left, then guided self-scheduling (each
    chunk the paths left / (2 x threads), at least MIN_TAIL_CHUNK), so the threads finish the round
    within about a tail chunk of each other instead of up to a batch (measured at 48x48 before: 4-5 %
    of two threads idle at round ends); one thread, or a round of at most threads x MIN_TAIL_CHUNK
    paths, gets even chunks (every thread some, of >= 256 paths). No chunk exceeds a batch (the
    batch bounds a thread's path memory). Which chunk a path falls in does not change its result."""
    if n_paths <= 0:
        return []
    if threads <= 1 or n_paths <= threads * MIN_TAIL_CHUNK:  # even chunks, none above a batch
        count = max(-(-n_paths // batch), min(threads, -(-n_paths // 256)))
        size = -(-n_paths // count)
        return [(k, min(k + size, n_paths)) for k in range(0, n_paths, size)]
    chunks, first = [], 0
    while first < n_paths:
        left = n_paths - first
        size = min(batch, max(MIN_TAIL_CHUNK, -(-left // (2 * threads))))
        if left - size < MIN_TAIL_CHUNK // 4 and left <= batch:  # no sliver of a chunk after this one
            size = left
        chunks.append((first, first + size))
        first += size
    return chunks
