// What the warp's boundary rules ask of espeak-ng's phoneme labels: whether a label begins with an
// oral closure, is a nasal, a closure voiced from its start, a vowel, a fricative or affricate, or a
// phone a voiced closure may hold; and which ARPAbet lip phone it stands for when the closure refiner
// (written for PocketSphinx's phones) looks at it. A label is a mnemonic of espeak-ng's English
// voices ("tS", "dZ", "@", "N") or IPA of every other voice ("tʃ", "ə", "ŋ"), with any length marks
// and diacritics after it ("pʰ", "mː", "b:"); these tests look at how it begins.
#pragma once

#include <string>

namespace lipsync::speech::detail {

/// A label of espeak-ng (mnemonic or IPA) that begins with an oral closure: a plosive or an
/// affricate (p, b, t, d, k, g, c, ɟ, q, ʈ, ɖ with any marks: "tʃ", "kʰ", "t#", "dZ").
bool starts_with_closure(const std::string& label);

/// The ARPAbet lip phone a label of espeak-ng (mnemonic or IPA) stands for, for the closure
/// refiner: p b m f v, alone or with length marks and diacritics ("pʰ", "mː", "b:"); else "X".
/// A /β/ is a /b/ too: espeak-ng says Catalan's and Spanish's /b/ between vowels as a fricative
/// that the recording (Festival's Catalan) may close.
std::string lip_phone_for_refiner(const std::string& label);

/// A nasal of espeak-ng (mnemonic or IPA): m n ŋ ɲ ɳ ɱ ("N" in the English mnemonics), with any marks.
bool is_nasal(const std::string& label);

/// A closure that is voiced from its start: a nasal, or a voiced stop or affricate (b d g ɡ ɟ ɖ ɢ,
/// with any marks: "bʲ", "dʒ", "dZ").
bool is_voiced_closure(const std::string& label);

/// A label of espeak-ng (IPA or English mnemonic) that is a vowel or a diphthong: its first letter is
/// one of a e i o u y, an IPA vowel letter, or a mnemonic vowel (@ 3 V I U O A E).
bool is_vowel(const std::string& label);

/// A fricative or affricate of espeak-ng (mnemonic or IPA), with any marks: its own sound is low in the
/// formant band and may be voiced, like a closure.
bool is_fricative_or_affricate(const std::string& label);

/// A phone whose sound would end a closure if it were said there: a vowel, a liquid or glide, or a stop
/// (whose closure a following /b/ shares). A voiced closure may hold such phones of espeak-ng's that the
/// speaker left out or that the warp pushed into it; a pause, nasal or fricative is a closure-like sound
/// of its own.
bool may_be_squeezed_into_closure(const std::string& label);

}  // namespace lipsync::speech::detail
