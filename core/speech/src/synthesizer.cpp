// espeak-ng synthesis with phoneme events (lipsync/speech/synthesizer.hpp).
//
// espeak-ng's output depends on what the process spoke before: its wave
// generator keeps state across calls in function-level statics (the pitch
// flutter index, the automatic gain, the phase of the glottal cycle), so the
// same text spoken twice in one process gives audio a few samples apart, with
// phoneme times shifted to match. espeak_Terminate does not reset them, and a
// second espeak_Initialize after it hangs (espeak-ng 1.51). So every synthesis
// runs in a process of its own, in which espeak-ng starts fresh: the audio and
// the timings depend on the text and the options alone, whichever process asks
// and whatever it spoke before (`lipsync say`, a long-running lipsyncd, a test).
// The asking process never initialises espeak-ng itself.
//
// That process is the running program started again (posix_spawn of
// /proc/self/exe), not a fork that goes on without exec: the asker is often
// multi-threaded (a gRPC server), and a forked child may only make
// async-signal-safe calls, for any other thread may have held a lock (the
// allocator's, stdio's, the sanitizers') at the moment of the fork. A forked
// child that synthesised hung on such a lock under AddressSanitizer. The new
// process knows it is a synthesis worker by LIPSYNC_ESPEAK_WORKER=1 in its
// environment: a constructor of this file, which every program that can ask
// for a synthesis links, sees it before main, reads the request from its
// standard input (a memfd the asker wrote), writes the result to its standard
// output (a pipe) and _exits, so none of the program's own start-up runs.
// Starting a process costs a few milliseconds beside the synthesis's tens.
//
// Phoneme names: espeak-ng names the phonemes of its events with the mnemonics
// of each language's phoneme table (`Y:`, `z2`, ...), which differ between
// tables, or, initialised with espeakINITIALIZE_PHONEME_IPA, with their IPA
// symbols, one vocabulary for all languages. English voices keep the mnemonics
// and the 'espeak' phone set (so English speech renders as it always did); every
// other voice speaks IPA, rendered through the 'ipa' phone set. Which one a voice
// is comes from its language in espeak-ng's voice list, read before
// initialisation (espeak_ListVoices needs only the data path), so the worker can
// initialise with the right flag (docs/languages.md).
#include "lipsync/speech/synthesizer.hpp"

#include <espeak-ng/espeak_ng.h>
#include <espeak-ng/speak_lib.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "lipsync/error.hpp"

namespace lipsync::speech {
namespace {

constexpr std::string_view kSource = "espeak-ng";

// One synthesis at a time (one child process at a time).
std::mutex espeak_mutex;
// espeak-ng's globals, in a child process only: one initialisation per process.
int espeak_rate_hz = 0;  // 0 until initialised

struct PhonemeStart {
  std::string name;
  std::int64_t sample;
};

// What the callback collects during one espeak_Synth call.
struct Collector {
  std::vector<std::int16_t> samples;
  std::vector<PhonemeStart> phonemes;
};
Collector* active_collector = nullptr;  // set during espeak_Synth

int collect(short* wav, int sample_count, espeak_EVENT* events) {
  Collector* collector = active_collector;
  if (collector == nullptr) return 0;
  if (wav != nullptr && sample_count > 0) collector->samples.insert(collector->samples.end(), wav, wav + sample_count);
  for (espeak_EVENT* event = events; event->type != espeakEVENT_LIST_TERMINATED; ++event) {
    if (event->type == espeakEVENT_PHONEME) {
      // `sample` is the event's position in the output, in samples (espeak-ng's
      // MarkerEvent); `audio_position` is the same in whole milliseconds.
      const std::string name(event->id.string, strnlen(event->id.string, sizeof event->id.string));
      collector->phonemes.push_back({name, event->sample});
    }
  }
  return 0;  // continue synthesis
}

std::string lower_ascii(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

/// espeak-ng's voice list (the voice files of espeak-ng-data), read once per process. It needs only
/// the data path, not espeak_Initialize: safe in the asking process too.
const std::vector<Voice>& voice_list() {
  static const std::vector<Voice> voices = [] {
    std::vector<Voice> out;
    espeak_ng_InitializePath(nullptr);
    const espeak_VOICE** listed = espeak_ListVoices(nullptr);
    for (std::size_t i = 0; listed != nullptr && listed[i] != nullptr; ++i) {
      Voice voice;
      voice.name = listed[i]->name != nullptr ? listed[i]->name : "";
      voice.identifier = listed[i]->identifier != nullptr ? listed[i]->identifier : "";
      // languages: a priority byte, a language name and its zero, ..., and a final zero.
      for (const char* language = listed[i]->languages; language != nullptr && language[0] != 0;
           language += std::strlen(language + 1) + 2) {
        voice.languages.emplace_back(language + 1);
      }
      out.push_back(std::move(voice));
    }
    return out;
  }();
  return voices;
}
std::mutex voice_list_mutex;

/// The voice espeak-ng would choose for `name` (as its own command line does: a voice name or file,
/// else a language), or nullptr. A variant after '+' ("en+f3") does not change the language.
const Voice* find_voice(std::string_view name) {
  const std::string wanted = lower_ascii(name.substr(0, name.find('+')));
  std::string spaced = wanted;  // "English_(America)", as espeak-ng --voices writes the name
  std::replace(spaced.begin(), spaced.end(), '_', ' ');
  const std::vector<Voice>& voices = voice_list();
  for (const Voice& voice : voices) {
    const std::string voice_name = lower_ascii(voice.name);
    const std::string identifier = lower_ascii(voice.identifier);
    const std::string file = identifier.substr(identifier.rfind('/') + 1);
    if (voice_name == wanted || voice_name == spaced || identifier == wanted || file == wanted) return &voice;
  }
  for (const Voice& voice : voices) {
    for (const std::string& language : voice.languages) {
      if (lower_ascii(language) == wanted) return &voice;
    }
  }
  return nullptr;
}

bool speaks_english(std::string_view voice_name) {
  const Voice* voice = find_voice(voice_name);
  if (voice == nullptr || voice->languages.empty()) return false;
  const std::string language = lower_ascii(voice->languages.front());
  return language == "en" || language.starts_with("en-");
}

/// espeak-ng's IPA names mark a switch to another language's phonemes ("(en)" inside a Greek
/// text) as a phoneme of its own: silence, as its mnemonic _^_ is in the 'espeak' set.
bool is_language_switch(std::string_view name) { return name.size() >= 3 && name.front() == '(' && name.back() == ')'; }

/// A length mark or a combining diacritic that espeak-ng's IPA names give as a phoneme of its own
/// (lv, ltg, kok: "ː"; bpy: U+0303): it lengthens or colours the phoneme before it, so it extends
/// that phoneme's interval instead of starting one.
bool is_lone_mark(std::string_view name) {
  if (name == "ː" || name == "ˑ") return true;
  if (name.empty() || name.size() % 2 != 0) return false;
  for (std::size_t i = 0; i < name.size(); i += 2) {  // U+0300..U+036F: CC 80..BF, CD 80..AF
    const auto lead = static_cast<unsigned char>(name[i]);
    const auto next = static_cast<unsigned char>(name[i + 1]);
    if (!((lead == 0xCC && next >= 0x80 && next <= 0xBF) || (lead == 0xCD && next >= 0x80 && next <= 0xAF))) {
      return false;
    }
  }
  return true;
}

void initialise_once(bool ipa) {
  if (espeak_rate_hz > 0) return;
  const int rate = espeak_Initialize(
      AUDIO_OUTPUT_SYNCHRONOUS, 0, nullptr,
      espeakINITIALIZE_PHONEME_EVENTS | espeakINITIALIZE_DONT_EXIT | (ipa ? espeakINITIALIZE_PHONEME_IPA : 0));
  if (rate <= 0) {
    throw InputError(std::string(kSource), 0,
                     "cannot initialise espeak-ng (is espeak-ng-data installed? 'apt-get install espeak-ng-data')");
  }
  espeak_SetSynthCallback(collect);
  espeak_rate_hz = rate;
}

/// The synthesis itself, in the child process.
Synthesis synthesize_here(std::string_view text, const SynthesisOptions& options) {
  const std::string source(kSource);
  const bool english = speaks_english(options.voice);
  initialise_once(!english);
  // A voice name or file, else a language ("en-gb", "fr-fr": the Language column of espeak-ng
  // --voices, which espeak_SetVoiceByName alone refuses) resolved to its voice file.
  bool found = espeak_SetVoiceByName(options.voice.c_str()) == EE_OK;
  if (const Voice* voice = found ? nullptr : find_voice(options.voice)) {
    const std::size_t plus = options.voice.find('+');
    const std::string variant = plus == std::string::npos ? "" : options.voice.substr(plus);
    found = espeak_SetVoiceByName((voice->identifier + variant).c_str()) == EE_OK;
  }
  if (!found) {
    throw InputError(source, 0, "unknown voice '" + options.voice + "' (see 'espeak-ng --voices')");
  }
  espeak_SetParameter(espeakRATE, options.words_per_minute, 0);

  Collector collector;
  const std::string text_z(text);  // espeak_Synth reads up to a terminating zero
  active_collector = &collector;
  const espeak_ERROR status =
      espeak_Synth(text_z.c_str(), text_z.size() + 1, 0, POS_CHARACTER, 0, espeakCHARS_UTF8, nullptr, nullptr);
  espeak_Synchronize();
  active_collector = nullptr;
  if (status != EE_OK) throw InputError(source, 0, "synthesis failed (espeak error " + std::to_string(status) + ")");

  Synthesis result;
  result.audio.sample_rate_hz = espeak_rate_hz;
  result.audio.samples = std::move(collector.samples);
  result.phonemes.source = source;
  result.phonemes.phone_set = english ? "espeak" : "ipa";
  const auto total = static_cast<std::int64_t>(result.audio.samples.size());
  const auto to_us = [&](std::int64_t sample) { return sample * 1'000'000 / espeak_rate_hz; };
  std::int64_t previous_start = 0;
  for (std::size_t i = 0; i < collector.phonemes.size(); ++i) {
    const std::int64_t start = std::clamp<std::int64_t>(collector.phonemes[i].sample, previous_start, total);
    const std::int64_t end = i + 1 < collector.phonemes.size()
                                 ? std::clamp<std::int64_t>(collector.phonemes[i + 1].sample, start, total)
                                 : total;
    previous_start = start;
    if (end <= start) continue;  // a zero-length event (espeak marks some stress changes this way)
    const std::string& name = collector.phonemes[i].name;
    if (!english && is_lone_mark(name) && !result.phonemes.intervals.empty()) {
      result.phonemes.intervals.back().end_us = to_us(end);
      continue;
    }
    result.phonemes.intervals.push_back({!english && is_language_switch(name) ? std::string() : name, to_us(start),
                                         to_us(end), static_cast<int>(i) + 1});
  }
  if (result.phonemes.intervals.empty()) throw InputError(source, 0, "espeak-ng produced no phonemes for the text");
  // The first phoneme starts at sample 0 and the phonemes tile the audio.
  if (result.phonemes.intervals.front().start_us > 0) {
    result.phonemes.intervals.insert(result.phonemes.intervals.begin(),
                                     {"", 0, result.phonemes.intervals.front().start_us, 0});
  }
  return result;
}

// --- the result through the pipe: [kind byte] then, for kOk, the rate, the samples and the
// intervals; for an error, its message. Integers in the machine's own byte order (same host).
constexpr char kOk = 0;
constexpr char kInputError = 1;
constexpr char kOtherError = 2;

template <typename T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}

void put_string(std::string& out, const std::string& text) {
  put(out, static_cast<std::uint64_t>(text.size()));
  out += text;
}

std::string encode(const Synthesis& synthesis) {
  std::string out(1, kOk);
  put_string(out, synthesis.phonemes.phone_set);
  put(out, synthesis.audio.sample_rate_hz);
  put(out, static_cast<std::uint64_t>(synthesis.audio.samples.size()));
  out.append(reinterpret_cast<const char*>(synthesis.audio.samples.data()),
             synthesis.audio.samples.size() * sizeof(std::int16_t));
  put(out, static_cast<std::uint64_t>(synthesis.phonemes.intervals.size()));
  for (const LabeledInterval& interval : synthesis.phonemes.intervals) {
    put_string(out, interval.label);
    put(out, interval.start_us);
    put(out, interval.end_us);
    put(out, interval.line);
  }
  return out;
}

/// Reads what encode() wrote; std::runtime_error if it is cut short.
class Decoder {
 public:
  explicit Decoder(std::string_view bytes) : bytes_(bytes) {}
  template <typename T>
  T get() {
    T value;
    std::memcpy(&value, take(sizeof value).data(), sizeof value);
    return value;
  }
  std::string get_string() { return std::string(take(get<std::uint64_t>())); }
  std::string_view take(std::size_t size) {
    if (size > bytes_.size()) throw std::runtime_error("espeak-ng: the synthesis process's answer is cut short");
    const std::string_view part = bytes_.substr(0, size);
    bytes_.remove_prefix(size);
    return part;
  }

 private:
  std::string_view bytes_;
};

Synthesis decode(std::string_view bytes) {
  Decoder in(bytes);
  const char kind = in.get<char>();
  if (kind == kInputError) throw InputError(std::string(kSource), 0, in.get_string());
  if (kind != kOk) throw std::runtime_error("espeak-ng: " + in.get_string());
  Synthesis result;
  result.phonemes.phone_set = in.get_string();
  result.audio.sample_rate_hz = in.get<int>();
  result.audio.samples.resize(in.get<std::uint64_t>());
  const std::string_view samples = in.take(result.audio.samples.size() * sizeof(std::int16_t));
  std::memcpy(result.audio.samples.data(), samples.data(), samples.size());
  result.phonemes.source = std::string(kSource);
  const auto count = in.get<std::uint64_t>();
  for (std::uint64_t i = 0; i < count; ++i) {
    LabeledInterval interval;
    interval.label = in.get_string();
    interval.start_us = in.get<std::int64_t>();
    interval.end_us = in.get<std::int64_t>();
    interval.line = in.get<int>();
    result.phonemes.intervals.push_back(std::move(interval));
  }
  return result;
}

// --- the request through the worker's standard input: the text, the voice, the rate.

std::string encode_request(std::string_view text, const SynthesisOptions& options) {
  std::string out;
  put_string(out, std::string(text));
  put_string(out, options.voice);
  put(out, options.words_per_minute);
  return out;
}

constexpr const char* kWorkerVariable = "LIPSYNC_ESPEAK_WORKER";

/// Writes all of `bytes` to `fd`; false on an error.
bool write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
  return true;
}

/// In the worker: reads the request from standard input, synthesises, writes the encoded
/// result (or the error) to standard output, and _exits.
[[noreturn]] void serve_one_synthesis() {
  std::string out;
  try {
    std::string request;
    char buffer[65536];
    for (;;) {
      const ssize_t n = ::read(STDIN_FILENO, buffer, sizeof buffer);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0)
        throw std::runtime_error("the synthesis worker cannot read its request: " + std::string(std::strerror(errno)));
      if (n == 0) break;
      request.append(buffer, static_cast<std::size_t>(n));
    }
    Decoder in(request);
    const std::string text = in.get_string();
    SynthesisOptions options;
    options.voice = in.get_string();
    options.words_per_minute = in.get<int>();
    out = encode(synthesize_here(text, options));
  } catch (const InputError& error) {
    out = std::string(1, kInputError);
    put_string(out, error.message());
  } catch (const std::exception& error) {
    out = std::string(1, kOtherError);
    put_string(out, error.what());
  }
  ::_exit(write_all(STDOUT_FILENO, out) ? 0 : 1);
}

/// Before main: a process started as a synthesis worker does only that.
[[gnu::constructor]] void become_a_synthesis_worker_if_asked() {
  const char* worker = std::getenv(kWorkerVariable);
  if (worker != nullptr && std::string_view(worker) == "1") serve_one_synthesis();
}

/// How long a worker may take before it is killed: generous (espeak-ng speaks a
/// 4,096-byte text in about a second), so that only a hung worker meets it.
std::chrono::milliseconds worker_deadline(std::size_t text_bytes) {
  return std::chrono::milliseconds(30'000 + 10 * static_cast<std::int64_t>(text_bytes));
}

/// Closes a file descriptor when it goes out of scope.
struct FileDescriptor {
  int fd = -1;
  FileDescriptor() = default;
  explicit FileDescriptor(int fd_in) : fd(fd_in) {}
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  ~FileDescriptor() { reset(); }
  void reset() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
};

std::runtime_error system_error(const std::string& what) {
  return std::runtime_error("espeak-ng: " + what + ": " + std::strerror(errno));
}

/// Starts this program again as a synthesis worker, hands it the request and returns its result.
Synthesis synthesize_in_worker(std::string_view text, const SynthesisOptions& options) {
  // The request in a memfd: written whole before the worker starts, so the asker never
  // blocks on (or gets SIGPIPE from) a worker that dies without reading.
  FileDescriptor request(::memfd_create("lipsync-espeak-request", MFD_CLOEXEC));
  if (request.fd < 0) throw system_error("cannot create the synthesis request");
  if (!write_all(request.fd, encode_request(text, options)) || ::lseek(request.fd, 0, SEEK_SET) != 0) {
    throw system_error("cannot write the synthesis request");
  }
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) throw system_error("cannot create a pipe");
  FileDescriptor answer_read(fds[0]);
  FileDescriptor answer_write(fds[1]);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, request.fd, STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, answer_write.fd, STDOUT_FILENO);
  std::vector<std::string> environment;
  for (char** variable = environ; *variable != nullptr; ++variable) {
    if (!std::string_view(*variable).starts_with(std::string(kWorkerVariable) + "="))
      environment.emplace_back(*variable);
  }
  environment.push_back(std::string(kWorkerVariable) + "=1");
  std::vector<char*> envp;
  for (std::string& variable : environment) envp.push_back(variable.data());
  envp.push_back(nullptr);
  char name[] = "lipsync-espeak-worker";
  char* argv[] = {name, nullptr};
  pid_t pid = 0;
  const int spawned = ::posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, argv, envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    errno = spawned;
    throw system_error("cannot start the synthesis process");
  }
  answer_write.reset();
  request.reset();

  std::string answer;
  const auto deadline = std::chrono::steady_clock::now() + worker_deadline(text.size());
  bool timed_out = false;
  int read_error = 0;
  char buffer[65536];
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      break;
    }
    pollfd readable{answer_read.fd, POLLIN, 0};
    const int ready = ::poll(&readable, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) continue;  // the deadline is checked above
    const ssize_t n = ready < 0 ? -1 : ::read(answer_read.fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) read_error = errno;  // the worker is killed below: nothing more can come
    if (n <= 0) break;
    answer.append(buffer, static_cast<std::size_t>(n));
  }
  if (timed_out || read_error != 0) ::kill(pid, SIGKILL);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) {
    throw std::runtime_error("espeak-ng: the synthesis process did not answer within " +
                             std::to_string(worker_deadline(text.size()).count() / 1000) + " s and was killed");
  }
  if (read_error != 0) {
    errno = read_error;
    throw system_error("cannot read the synthesis process's answer");
  }
  if (WIFSIGNALED(status)) {
    throw std::runtime_error("espeak-ng: the synthesis process died with signal " + std::to_string(WTERMSIG(status)));
  }
  if (answer.empty()) {
    throw std::runtime_error("espeak-ng: the synthesis process ended (exit status " +
                             std::to_string(WEXITSTATUS(status)) + ") without an answer");
  }
  return decode(answer);
}

}  // namespace

std::vector<Voice> list_voices() {
  const std::lock_guard lock(voice_list_mutex);
  return voice_list();
}

std::string phone_set_for_voice(std::string_view voice) {
  const std::lock_guard lock(voice_list_mutex);
  return speaks_english(voice) ? "espeak" : "ipa";
}

Synthesis synthesize(std::string_view text, const SynthesisOptions& options) {
  const std::string source(kSource);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) throw InputError(source, 0, "the text is empty");
  if (options.words_per_minute < kWordsPerMinuteSetting.min || options.words_per_minute > kWordsPerMinuteSetting.max) {
    throw InputError(source, 0,
                     out_of_range_text("speaking rate (words per minute)", std::to_string(options.words_per_minute),
                                       range_text(kWordsPerMinuteSetting)));
  }
  const std::lock_guard lock(espeak_mutex);
  return synthesize_in_worker(text, options);
}

}  // namespace lipsync::speech
