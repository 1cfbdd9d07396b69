// Audio in, any language: a recording aligned against espeak-ng's own rendering of
// its transcript, the way aeneas aligns words, here at phoneme level.
//
// PocketSphinx knows English only. For any espeak-ng voice the transcript is
// spoken by espeak-ng (synthesizer.hpp), whose phonemes come with exact times on
// its own audio. Both audios become MFCC frames every 10 ms
// (acoustic_features.hpp), and dynamic time warping finds the cheapest monotone
// path through their frame-to-frame distances (Euclidean, steps →, ↓ and ↘, the
// diagonal counted twice so that no shape of path is favoured). Each phoneme
// boundary of the synthesis is carried along the path to the recording: a
// boundary between synthesis frames i−1 and i lands between the last recording
// frame matched to i−1 and the first matched to i, interpolated within the frame.
// A frame matched to a long run of the other's (→ or ↓ steps past the eighth, outside
// pauses) pays extra per step (StretchCost), so that a frame only a little nearer cannot
// take a whole vowel from the frames it belongs to.
//
// A speaker pauses where espeak-ng does not (between words, or longer at a comma), and the
// warp then matches the pause to whatever espeak-ng says there, a closure or a vowel, and
// carries the next boundaries into the pause. So after a first warp each pause of the recording
// (120 ms or more, inside its speech) matched to 100 ms or more less pause of the rendering is
// put into espeak-ng's audio as silence, at the phone boundary nearest the rendering frame that
// takes most of it (before a stop's closure), and the warp is done again; the second warp is
// kept when its mean distance is no larger than the first's.
//
// espeak-ng reports a stop at its burst, so before the warp the lip phones' starts
// are moved to the closures in espeak-ng's own audio (closure_refiner.hpp), and
// after it the lip phones' boundaries move to the recording's energy steps, as
// with PocketSphinx. A stop after a pause shows no closure in either audio (it is
// as silent as the pause): it arrives at the recording's burst and starts 80 ms
// before it. Nor does a stop after a nasal (/m b/, /n d/: the nasal's closure goes on
// into it, and espeak-ng's nasal lasts until the burst): it starts 60 ms before its
// burst. A /β/ (espeak-ng's Catalan and Spanish /b/ between vowels) is refined as a /b/.
//
// Bounds: the path is searched in a band around the line from the start of
// speech in one audio to the start in the other, and from end to end (leading
// and trailing pauses matched to each other), `band_s` wide on each side of it,
// so time and memory grow with length × band (docs/languages.md, "Bounds and errors", gives
// them for a 10-minute file). A recording that does not say the transcript in that voice's
// language shows as a mean distance along the path near that of unrelated frames, and is an
// error rather than a guess.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/speech/acoustic_features.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/synthesizer.hpp"

namespace lipsync::speech {

/// The closure refiner's settings after a warp: its boundaries are less exact than
/// PocketSphinx's, so the energy steps are looked for farther from them.
inline ClosureRefinerOptions dtw_refiner_options() {
  ClosureRefinerOptions options;
  options.search_us = 50'000;
  // espeak-ng's pauses are phonemes of its rendering, carried across: one it writes after a /p/
  // (Italian "compra": p _ r) stays.
  options.pause_after_stop_is_its_closure = false;
  return options;
}

/// What the warp charges, on top of the frames' distance, for matching one frame to a long run of
/// frames of the other audio: each → or ↓ step past a run's first `free_frames` costs `cost` more,
/// unless either frame is at pause level (pauses and closures differ freely in length).
///
/// Without it a frame that is only a little closer takes a whole stretch: Festival's Finnish says the
/// /aː aː/ of "leipaa aamulla" 333 ms long, espeak-ng 270 ms, yet the warp matched one frame of
/// espeak-ng's /m/ (quiet, like Festival's vowel as it dips between the words) to 310 ms of the vowel
/// and all 27 frames of espeak-ng's vowel to one of Festival's, putting the /m/ 275 ms early; with
/// this cost it is 6 ms late. 8 frames (80 ms on one frame) and 20 (a third of the mean frame
/// distance along the warps of Festival's sentences, 50 to 61, distances of mfcc_features) were
/// chosen on the sentences of docs/languages.md: 10 did not move that /m/; 40, or runs free only
/// up to 3 to 6 frames, made other rows worse.
struct StretchCost {
  std::size_t free_frames = 8;
  double cost = 20.0;
};

struct DtwAlignmentOptions {
  /// What the recording says (UTF-8, in the voice's language).
  std::string transcript;
  /// The voice that renders the transcript; its rate should be close to the speaker's.
  SynthesisOptions synthesis;
  /// Longest audio accepted, seconds.
  double max_duration_s = 600;
  /// How far the path may stray from the proportional line, seconds, each side.
  double band_s = 5.0;
  /// What matching one frame to many costs in the warp.
  StretchCost stretch;
  /// The largest mean distance of the frames the warp matches, as a share of the mean distance of
  /// unrelated frames (the recording's against the synthesis's across the whole matrix), accepted
  /// as the same words. On Festival's voices the right transcript gives 0.40 to 0.65, white noise
  /// 0.71; another sentence of similar length in the same language gives 0.50 to 0.67 and is
  /// not always refused.
  double max_distance_ratio = 0.68;
  /// Move the lip phones' boundaries to the energy steps (of the synthesis before the
  /// warp and of the recording after it).
  bool refine_closures = true;
  ClosureRefinerOptions refiner = dtw_refiner_options();
};

/// A warp between frame sequences `a` (rows) and `b` (columns): for each frame of
/// `a`, the first and last frame of `b` the path matches to it.
struct WarpPath {
  std::vector<std::size_t> first, last;
  double mean_distance = 0;       ///< mean frame distance along the path
  double unrelated_distance = 0;  ///< mean distance of frames of a to frames of b across the whole matrix
};

/// The cheapest monotone path from (0, 0) to (a.size()−1, b.size()−1) within
/// `band_frames` of the line through (0, 0), (a_speech_start, b_speech_start),
/// (a_speech_end, b_speech_end), (a.size()−1, b.size()−1), long runs of → or ↓ steps
/// charged `stretch` (its mean_distance is that of the frames alone). Needs frames in both.
WarpPath warp(const FeatureFrames& a, const FeatureFrames& b, std::size_t band_frames,
              std::pair<std::size_t, std::size_t> a_speech, std::pair<std::size_t, std::size_t> b_speech,
              const StretchCost& stretch = {});

/// The time in b of the time `a_us` in a, µs (frame centres interpolated).
std::int64_t carry_time_us(const WarpPath& path, std::int64_t a_us);

/// The frames from the first to the last whose level is within 35 dB of the loudest (the speech).
std::pair<std::size_t, std::size_t> speech_frames(const FeatureFrames& frames);

/// A pause the recording has and espeak-ng's rendering lacks: `duration_us` of silence that
/// belongs in the rendering at the start of its phone `phone`.
struct MissingPause {
  std::size_t phone;
  std::int64_t duration_us;
};

/// The recording's pauses (120 ms or more of frames 35 dB under its loudest, between the first and
/// last of its speech) that `path` (rendering rows, recording columns) matches to 100 ms or more
/// fewer pause-level frames of the rendering: for each, the phone of `phones` (the rendering's,
/// tiling it) whose start is nearest the rendering frame that takes the most of the pause, and the
/// pause's length less the rendering's pause-level frames matched to it.
std::vector<MissingPause> missing_pauses(const WarpPath& path, const FeatureFrames& rendering,
                                         const std::vector<LabeledInterval>& phones, const FeatureFrames& recording);

/// A pause espeak-ng's rendering has and the recording lacks: `duration_us` to cut from the
/// middle of the rendering's pause that runs from its phone `first_phone` to `last_phone`
/// (consecutive pauses are one).
struct ExtraPause {
  std::size_t first_phone;
  std::size_t last_phone;
  std::int64_t duration_us;
};

/// The rendering's pauses inside its speech (runs of `phones` labelled "", neither first nor last)
/// that `path` matches to 50 ms or more fewer frames of the recording's own pauses (120 ms or more
/// at 35 dB under its loudest): for each, its pause-level frames less those the recording's pauses
/// give it, kept under the pause's length by one frame.
std::vector<ExtraPause> extra_pauses(const WarpPath& path, const FeatureFrames& rendering,
                                     const std::vector<LabeledInterval>& phones, const FeatureFrames& recording);

/// An /m/ after a vowel whose start `bounds` (bounds[k] the start of phones[k], bounds[size] the
/// end) carries into the recording's vowel, the formant band's level `level_db` (10 ms windows
/// every ms, formant_band_levels_db) there within 4 dB of the vowel's loudest and not falling over
/// the next 30 ms: it starts where the level first falls 6 dB under that loudest (the murmur), at
/// the steepest 10 ms fall within 10 ms of that, when that is within its interval and 150 ms.
void start_bilabial_nasals_at_murmur(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                     const std::vector<double>& level_db);

/// A voiced /b/ of `phones` (espeak-ng's labels: b, β with any marks; not after a pause or nasal) whose
/// start bounds[k] (bounds[k] starts phones[k], bounds.back() is the end) lies inside a voiced closure
/// of `recording` (its 400–3500 Hz level 10 dB under the sound before and the release after for 40 ms
/// or more, its level below 400 Hz, the voicing bar, held) starts where that closure begins: at the onset of the
/// formant band's fall, or where the voicing bar rises in a voiceless stop's silence. The phones
/// between (vowels, liquids, glides, stops only; a fricative or nasal there leaves the /b/ alone) are
/// squeezed before it, 10 ms each where there is room.
void start_voiced_bilabials_at_closures(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                        const PcmAudio& recording);

/// Aligns `audio` (any rate) against options.synthesis's rendering of options.transcript:
/// phones in phone_set_for_voice(voice) ("" for pauses), tiling [0, audio end]; no words.
/// `source` names the audio in errors. Throws InputError: an empty transcript, an unknown
/// voice, silent or too long audio, a recording that does not match the transcript.
Alignment align_speech_to_synthesis(const PcmAudio& audio, std::string_view source, const DtwAlignmentOptions& options);

}  // namespace lipsync::speech
