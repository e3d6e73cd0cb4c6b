"""Rounds under a time limit (round_schedule.py) and render()'s Time Limit: the render stops on the
clock, and what it renders is exactly the image of that many samples."""
import numpy as np
import pytest

from volpath_native import RenderSettings, SceneError, render
from volpath_native.round_schedule import (MAX_BATCHES_PER_ROUND, UPDATE_INTERVAL, fixed_round_samples,
                                          timed_round_samples)
from volpath_native.scene_schema import check_settings

from test_render_api import _scene


def test_rounds_without_a_limit_are_a_batch_per_thread():
    assert fixed_round_samples(samples=1000, threads=2, batch=65536, pixels=48 * 48) == 56
    assert fixed_round_samples(samples=8, threads=2, batch=65536, pixels=48 * 48) == 8
    assert fixed_round_samples(samples=1000, threads=1, batch=1024, pixels=1920 * 1080) == 1


def test_first_round_is_one_sample_then_rounds_fill_the_interval_and_never_the_time_left():
    kw = dict(threads=2, batch=65536, pixels=48 * 48)
    assert timed_round_samples(0, 10 ** 6, 0.0, 4.0, 0.0, **kw) == 1
    # 1 ms per pass: an update interval's worth, up to the memory bound
    assert timed_round_samples(1, 10 ** 6, 0.01, 4.0, 1e-3, **kw) == min(int(UPDATE_INTERVAL / 1e-3), MAX_BATCHES_PER_ROUND * 2 * 65536 // (48 * 48))
    # 0.3 s left at 0.1 s per pass: three passes, not ten
    assert timed_round_samples(5, 10 ** 6, 3.7, 4.0, 0.1, **kw) == 3
    # less than half a pass left, or the limit reached: stop
    assert timed_round_samples(5, 10 ** 6, 3.96, 4.0, 0.1, **kw) == 0
    assert timed_round_samples(5, 10 ** 6, 4.0, 4.0, 1e-6, **kw) == 0
    # the sample count still caps the render
    assert timed_round_samples(98, 100, 0.5, 4.0, 1e-3, **kw) == 2
    assert timed_round_samples(100, 100, 0.5, 4.0, 1e-3, **kw) == 0


def test_time_limited_render_stops_on_the_clock_with_the_image_of_its_sample_count():
    limit = 0.6
    render(_scene(samples=1))  # kernels loaded (or compiled) before the clock matters
    timed = render(_scene(samples=1 << 20, time_limit=limit, threads=2))
    assert 1 < timed.samples < 1 << 20 and not timed.cancelled
    # set-up is not counted; a round never starts past the limit, nor needs more than the time left
    assert timed.seconds < limit + 2.0
    fixed = render(_scene(samples=timed.samples, threads=1, batch_size=4096))
    # the same samples of every pixel, only summed in other rounds
    np.testing.assert_allclose(timed.image, fixed.image, rtol=1e-6, atol=1e-9)
    assert np.all(np.isfinite(timed.image))


def test_a_negative_or_non_finite_time_limit_is_refused_naming_the_field():
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(SceneError, match="time_limit"):
            check_settings(RenderSettings(time_limit=bad))


def test_a_round_splits_into_batches_then_a_shrinking_tail():
    """round_chunks covers the round's paths in order without gaps: batches first, then chunks
    shrinking to MIN_TAIL_CHUNK (the threads finish together), no sliver at the end; small rounds
    spread over the threads, one thread takes batches; no chunk exceeds the batch."""
    from volpath_native.round_schedule import MIN_TAIL_CHUNK, round_chunks

    def sizes(n, batch, threads):
        chunks = round_chunks(n, batch, threads)
        assert chunks[0][0] == 0 and chunks[-1][1] == n
        assert all(a[1] == b[0] for a, b in zip(chunks, chunks[1:]))
        return [end - first for first, end in chunks]

    big = sizes(500 * 48 * 48, 65536, 2)
    assert big[0] == 65536 and sorted(big[:-1], reverse=True) == big[:-1]  # largest first, then shrinking
    assert max(big[-6:]) <= 65536 // 4 and big[-2] == MIN_TAIL_CHUNK
    assert MIN_TAIL_CHUNK <= big[-1] < MIN_TAIL_CHUNK * 5 // 4  # the sliver joined the last chunk
    assert sizes(48 * 48, 65536, 2) == [1152, 1152]  # the first timed round: one pass, both threads
    assert sizes(300, 65536, 4) == [150, 150]  # chunks of at least 256 paths (rounded up)
    assert sizes(10 ** 6, 65536, 1) == [62500] * 16  # one thread: no tail to balance
    assert round_chunks(0, 65536, 2) == []
    for n in (8000, 2 * 4096 + 1500, 20000, 10 ** 5):  # a small Batch Size bounds every chunk
        assert max(sizes(n, 1024, 2)) <= 1024
