// Preloaded by `deploy/sanitize.sh tsan` (LD_PRELOAD; built there, in no other
// build): states for ThreadSanitizer the synchronisation that Debian's uninstrumented
// abseil and protobuf do and TSan cannot see (docs/security.md, "Sanitizers"). Each
// interposer calls the real function (dlsym RTLD_NEXT; Debian 12's abseil 20220623,
// inline namespace debian3, and protobuf 3.21) and states one edge:
//
// - abseil's Mutex, which gRPC takes (through gpr_mu) for most of its hand-offs between
//   threads: acquire after a lock, release before an unlock, both around a CondVar wait.
// - protobuf's parse of a received message, which gRPC runs on whichever thread completed
//   the read: acquire the message before the parse, release it after. With the release
//   that a reactor's StartRead(message) makes (proto/include/lipsync/tsan_handoff.hpp),
//   this says that the reactor's use of the previous message happens before gRPC clears
//   and refills it, and the parse before the reaction that reads it.
//
// Interposition only reaches calls that go through the dynamic linker: gRPC's calls into
// abseil from its shared libraries, and the parse call in gRPC's inline header code.
#include <absl/synchronization/mutex.h>
#include <dlfcn.h>
#include <google/protobuf/message_lite.h>

#include <cstdio>
#include <cstdlib>
extern "C" void __tsan_acquire(void*);
extern "C" void __tsan_release(void*);
template <class F>
F real(const char* name) {
  static_assert(sizeof(F) == sizeof(void*));
  void* p = dlsym(RTLD_NEXT, name);
  if (p == nullptr) {
    std::fprintf(stderr, "tsan_edges: %s not found (not Debian 12's abseil and protobuf?)\n", name);
    std::abort();
  }
  F f;
  __builtin_memcpy(&f, &p, sizeof p);
  return f;
}
namespace absl {
inline namespace debian3 {
using MFn = void (*)(Mutex*);
using MBool = bool (*)(Mutex*);
void Mutex::Lock() {
  static auto f = real<MFn>("_ZN4absl7debian35Mutex4LockEv");
  f(this);
  __tsan_acquire(this);
}
void Mutex::Unlock() {
  static auto f = real<MFn>("_ZN4absl7debian35Mutex6UnlockEv");
  __tsan_release(this);
  f(this);
}
void Mutex::ReaderLock() {
  static auto f = real<MFn>("_ZN4absl7debian35Mutex10ReaderLockEv");
  f(this);
  __tsan_acquire(this);
}
void Mutex::ReaderUnlock() {
  static auto f = real<MFn>("_ZN4absl7debian35Mutex12ReaderUnlockEv");
  __tsan_release(this);
  f(this);
}
bool Mutex::TryLock() {
  static auto f = real<MBool>("_ZN4absl7debian35Mutex7TryLockEv");
  bool r = f(this);
  if (r) __tsan_acquire(this);
  return r;
}
bool Mutex::ReaderTryLock() {
  static auto f = real<MBool>("_ZN4absl7debian35Mutex13ReaderTryLockEv");
  bool r = f(this);
  if (r) __tsan_acquire(this);
  return r;
}
void Mutex::LockWhen(const Condition& c) {
  static auto f = real<void (*)(Mutex*, const Condition&)>("_ZN4absl7debian35Mutex8LockWhenERKNS0_9ConditionE");
  f(this, c);
  __tsan_acquire(this);
}
void Mutex::Await(const Condition& c) {
  static auto f = real<void (*)(Mutex*, const Condition&)>("_ZN4absl7debian35Mutex5AwaitERKNS0_9ConditionE");
  __tsan_release(this);
  f(this, c);
  __tsan_acquire(this);
}
void CondVar::Wait(Mutex* mu) {
  static auto f = real<void (*)(CondVar*, Mutex*)>("_ZN4absl7debian37CondVar4WaitEPNS0_5MutexE");
  __tsan_release(mu);
  f(this, mu);
  __tsan_acquire(mu);
}
bool CondVar::WaitWithTimeout(Mutex* mu, Duration d) {
  static auto f = real<bool (*)(CondVar*, Mutex*, Duration)>(
      "_ZN4absl7debian37CondVar15WaitWithTimeoutEPNS0_5MutexENS0_8DurationE");
  __tsan_release(mu);
  bool r = f(this, mu, d);
  __tsan_acquire(mu);
  return r;
}
bool CondVar::WaitWithDeadline(Mutex* mu, Time t) {
  static auto f =
      real<bool (*)(CondVar*, Mutex*, Time)>("_ZN4absl7debian37CondVar16WaitWithDeadlineEPNS0_5MutexENS0_4TimeE");
  __tsan_release(mu);
  bool r = f(this, mu, t);
  __tsan_acquire(mu);
  return r;
}
}  // namespace debian3
}  // namespace absl

namespace google::protobuf {
bool MessageLite::ParseFromZeroCopyStream(io::ZeroCopyInputStream* input) {
  static auto f = real<bool (*)(MessageLite*, io::ZeroCopyInputStream*)>(
      "_ZN6google8protobuf11MessageLite23ParseFromZeroCopyStreamEPNS0_2io19ZeroCopyInputStreamE");
  __tsan_acquire(this);
  bool r = f(this, input);
  __tsan_release(this);
  return r;
}
}  // namespace google::protobuf
