"""lipsync_client.tts: exact µs parsing of flite and Festival timings (real tool output).

Run: PYTHONPATH=clients/python /usr/bin/python3 -m unittest -v test_tts  (from clients/python/tests)
Needs flite and festival (+ festvox-kallpc16k) installed; it fails, not skips, without them.
"""

import shutil
import unittest

from lipsync_client import tts
from lipsync_client.tts import TimedPhoneme

# Recorded from `flite -voice slt -psdur -t "Peter picked a peck of pepper." -o none` (flite 2.2).
FLITE_RECORDED = (
    "pau:0.193 p:0.240 iy:0.332 t:0.361 er:0.426 p:0.549 ih:0.627 k:0.714 t:0.734 ax:0.771 "
    "p:0.873 eh:0.971 k:1.058 ah:1.095 v:1.145 p:1.199 eh:1.277 p:1.371 er:1.544 pau:1.717 \n"
)

RADIO_PHONES = set(
    "aa ae ah ao aw ay b ch d dh eh er ey f g hh ih iy jh k l m n ng ow oy p r s sh t th uh uw "
    "v w y z zh ax axr dx el em en nx hv pau h# brth".split()
)


class SecondsToMicroseconds(unittest.TestCase):
    def test_exact_decimal_conversion(self):
        self.assertEqual(tts.seconds_to_us("0.171"), 171000)
        self.assertEqual(tts.seconds_to_us("0"), 0)
        self.assertEqual(tts.seconds_to_us("1.544"), 1544000)
        self.assertEqual(tts.seconds_to_us("0.22000001"), 220000)
        self.assertEqual(tts.seconds_to_us("1.5e-3"), 1500)
        self.assertEqual(tts.seconds_to_us("86400"), 86400 * 10**6)

    def test_no_binary_float_error(self):
        # float("0.3") * 1e6 = 299999.99999999994; decimal parsing gives 300000 exactly,
        # and values a float32 cannot hold keep every microsecond.
        self.assertEqual(tts.seconds_to_us("0.3"), 300000)
        self.assertEqual(tts.seconds_to_us("4000.000001"), 4000000001)
        self.assertEqual(tts.seconds_to_us("16777.217"), 16777217000)

    def test_rounds_half_away_from_zero_beyond_microseconds(self):
        self.assertEqual(tts.seconds_to_us("0.0000005"), 1)
        self.assertEqual(tts.seconds_to_us("0.0000004999"), 0)
        self.assertEqual(tts.seconds_to_us("0.0000025"), 3)

    def test_rejects(self):
        for text in ("", "abc", "-0.1", "nan", "inf", "1:2", "86400.000001"):
            with self.subTest(text=text), self.assertRaises(ValueError):
                tts.seconds_to_us(text)


class FliteParsing(unittest.TestCase):
    def test_recorded_output(self):
        phonemes = tts.parse_flite_psdur(FLITE_RECORDED)
        self.assertEqual(len(phonemes), 20)
        self.assertEqual(phonemes[0], TimedPhoneme("pau", 0, 193000))
        self.assertEqual(phonemes[1], TimedPhoneme("p", 193000, 240000))
        self.assertEqual(phonemes[-1], TimedPhoneme("pau", 1544000, 1717000))
        for previous, current in zip(phonemes, phonemes[1:]):
            self.assertEqual(previous.end_us, current.start_us)
        for phoneme in phonemes:
            self.assertIsInstance(phoneme.start_us, int)
            self.assertIsInstance(phoneme.end_us, int)

    def test_malformed(self):
        for text in ("pau", ":0.1", "pau:x", "pau:0.2 p:0.1", "pau:-1"):
            with self.subTest(text=text), self.assertRaises(tts.TTSError):
                tts.parse_flite_psdur(text)

    def test_real_flite(self):
        self.assertIsNotNone(shutil.which("flite"), "flite is not installed (apt-get install flite)")
        phonemes = tts.flite_phonemes("Peter picked a peck of pepper.")
        # flite is deterministic: the same text gives the recorded timings.
        self.assertEqual(phonemes, tts.parse_flite_psdur(FLITE_RECORDED))
        self.assertLessEqual({p.label for p in phonemes}, RADIO_PHONES)

    def test_missing_program_is_a_clear_error(self):
        with self.assertRaises(tts.TTSUnavailableError) as caught:
            tts.flite_phonemes("hello", flite="lipsync-no-such-flite")
        self.assertIn("apt-get install flite", str(caught.exception))
        self.assertIsInstance(caught.exception, FileNotFoundError)


class FestivalParsing(unittest.TestCase):
    def test_segment_lines(self):
        phonemes = tts.parse_festival_segments("pau 0 0.22000001\np 0.22000001 0.32152608\n")
        self.assertEqual(phonemes, [TimedPhoneme("pau", 0, 220000), TimedPhoneme("p", 220000, 321526)])
        with self.assertRaises(tts.TTSError):
            tts.parse_festival_segments("p 0.3 0.2\n")
        with self.assertRaises(tts.TTSError):
            tts.parse_festival_segments("p 0 0.2\nb 0.1 0.3\n")

    def test_real_festival(self):
        self.assertIsNotNone(shutil.which("festival"),
                             "festival is not installed (apt-get install festival festvox-kallpc16k)")
        # Quotes and backslashes in the text must not break the generated Scheme script.
        phonemes = tts.festival_phonemes('Peter said "pepper" \\ twice.')
        labels = [p.label for p in phonemes]
        self.assertEqual(labels[:3], ["pau", "p", "iy"])
        self.assertEqual(labels[-1], "pau")
        self.assertLessEqual(set(labels), RADIO_PHONES)
        self.assertEqual(phonemes[0].start_us, 0)
        for previous, current in zip(phonemes, phonemes[1:]):
            self.assertEqual(previous.end_us, current.start_us)
            self.assertLess(current.start_us, current.end_us)

    def test_unknown_voice_is_an_error(self):
        with self.assertRaisesRegex(tts.TTSError, "voice_no_such_voice"):
            tts.festival_phonemes("hello", voice="no_such_voice")


class FrontEndChoice(unittest.TestCase):
    def test_auto_prefers_flite(self):
        self.assertEqual(tts.timed_phonemes("Peter picked a peck of pepper."),
                         tts.parse_flite_psdur(FLITE_RECORDED))

    def test_unknown_frontend(self):
        with self.assertRaises(ValueError):
            tts.timed_phonemes("hello", frontend="espeak")


if __name__ == "__main__":
    unittest.main()
