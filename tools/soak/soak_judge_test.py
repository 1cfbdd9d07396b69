"""Tests of soak_judge.judge on synthetic quiet-sample series: it must pass a flat
series with noise or with glibc's swings between two levels, and fail a steadily
rising one (a leak, also under the swings) and a descriptor leak."""
import random
import unittest

from soak_judge import judge


def noisy(base, count, spread, seed, step=0):
    rng = random.Random(seed)
    return [base + i * step + rng.randint(-spread, spread) for i in range(count)]


class SoakJudgeTest(unittest.TestCase):
    def test_flat_memory_with_noise_passes(self):
        self.assertEqual(judge(noisy(60_000, 12, 6_000, 1), noisy(20, 12, 1, 2), 16_384, 8), [])

    def test_memory_rising_by_3_mb_per_sample_fails(self):
        failures = judge(noisy(60_000, 12, 2_000, 3, step=3_000), [20] * 12, 16_384, 8)
        self.assertEqual(len(failures), 1)
        self.assertIn("resident memory grew", failures[0])

    def test_descriptors_leaking_one_per_sample_fail(self):
        failures = judge([60_000] * 30, list(range(20, 50)), 16_384, 8)
        self.assertEqual(len(failures), 1)
        self.assertIn("open file descriptors grew", failures[0])

    def test_one_fat_quiet_moment_at_the_end_passes(self):
        self.assertEqual(judge([60_000] * 11 + [120_000], [20] * 12, 16_384, 8), [])

    def test_memory_switching_between_two_levels_passes(self):
        rng = random.Random(4)
        levels = [rng.choice([65_000, 100_000]) for _ in range(11)] + [100_000] * 10 + [65_000]
        self.assertEqual(judge(levels, [16] * len(levels), 16_384, 8), [])

    def test_a_leak_under_the_switching_fails(self):
        rng = random.Random(5)
        leaking = [rng.choice([65_000, 100_000]) + i * 2_000 for i in range(30)]
        failures = judge(leaking, [16] * 30, 16_384, 8)
        self.assertEqual(len(failures), 1)
        self.assertIn("resident memory grew", failures[0])

    def test_too_few_samples_is_a_failure_that_says_run_longer(self):
        failures = judge([60_000, 61_000], [20, 20], 16_384, 8)
        self.assertEqual(len(failures), 1)
        self.assertIn("run longer", failures[0])


if __name__ == "__main__":
    unittest.main()
