// Probe, preloaded by `deploy/sanitize.sh tsan-clang` only (no CI step): makes abseil's Mutex visible to ThreadSanitizer
// by interposing its entry points (docs/security.md, "Where TSan stands"). Debian's gRPC
// takes abseil's Mutex (through gpr_mu) for most of its hand-offs between threads, and TSan
// cannot see it (abseil is not instrumented). Each interposer calls the real function
// (dlsym RTLD_NEXT, Debian 12's abseil 20220623, inline namespace debian3) and states the
// mutex's edge: acquire after a lock, release before an unlock, both around a CondVar wait.
// Build and use (TSan build in build-tsan/):
//   g++ -std=c++17 -O1 -shared -fPIC -o build-tsan/libabsl_mutex_tsan.so deploy/tsan_absl_mutex_probe.cpp -ldl
//   LD_PRELOAD=$PWD/build-tsan/libabsl_mutex_tsan.so TSAN_OPTIONS=... ctest --test-dir build-tsan -R ...
// Known problem: with the GCC TSan build, tenants_test's TheSessionAndSubscriberQuotasRefuseNamingTheQuota did not end
// with it (not investigated); with the clang build (tsan-clang) every tenants_test test ended.
#include <dlfcn.h>

#include <cstdio>
#include <cstdlib>

#include <absl/synchronization/mutex.h>
extern "C" void __tsan_acquire(void*);
extern "C" void __tsan_release(void*);
template <class F> F real(const char* name) {
  static_assert(sizeof(F) == sizeof(void*));
  void* p = dlsym(RTLD_NEXT, name);
  if (p == nullptr) {
    std::fprintf(stderr, "tsan_absl_mutex_probe: %s not found (not Debian 12's abseil?)\n", name);
    std::abort();
  }
  F f; __builtin_memcpy(&f, &p, sizeof p); return f;
}
namespace absl { inline namespace debian3 {
using MFn = void (*)(Mutex*);
using MBool = bool (*)(Mutex*);
void Mutex::Lock() { static auto f = real<MFn>("_ZN4absl7debian35Mutex4LockEv"); f(this); __tsan_acquire(this); }
void Mutex::Unlock() { static auto f = real<MFn>("_ZN4absl7debian35Mutex6UnlockEv"); __tsan_release(this); f(this); }
void Mutex::ReaderLock() { static auto f = real<MFn>("_ZN4absl7debian35Mutex10ReaderLockEv"); f(this); __tsan_acquire(this); }
void Mutex::ReaderUnlock() { static auto f = real<MFn>("_ZN4absl7debian35Mutex12ReaderUnlockEv"); __tsan_release(this); f(this); }
bool Mutex::TryLock() { static auto f = real<MBool>("_ZN4absl7debian35Mutex7TryLockEv"); bool r = f(this); if (r) __tsan_acquire(this); return r; }
bool Mutex::ReaderTryLock() { static auto f = real<MBool>("_ZN4absl7debian35Mutex13ReaderTryLockEv"); bool r = f(this); if (r) __tsan_acquire(this); return r; }
void Mutex::LockWhen(const Condition& c) { static auto f = real<void (*)(Mutex*, const Condition&)>("_ZN4absl7debian35Mutex8LockWhenERKNS0_9ConditionE"); f(this, c); __tsan_acquire(this); }
void Mutex::Await(const Condition& c) { static auto f = real<void (*)(Mutex*, const Condition&)>("_ZN4absl7debian35Mutex5AwaitERKNS0_9ConditionE"); __tsan_release(this); f(this, c); __tsan_acquire(this); }
void CondVar::Wait(Mutex* mu) { static auto f = real<void (*)(CondVar*, Mutex*)>("_ZN4absl7debian37CondVar4WaitEPNS0_5MutexE"); __tsan_release(mu); f(this, mu); __tsan_acquire(mu); }
bool CondVar::WaitWithTimeout(Mutex* mu, Duration d) { static auto f = real<bool (*)(CondVar*, Mutex*, Duration)>("_ZN4absl7debian37CondVar15WaitWithTimeoutEPNS0_5MutexENS0_8DurationE"); __tsan_release(mu); bool r = f(this, mu, d); __tsan_acquire(mu); return r; }
bool CondVar::WaitWithDeadline(Mutex* mu, Time t) { static auto f = real<bool (*)(CondVar*, Mutex*, Time)>("_ZN4absl7debian37CondVar16WaitWithDeadlineEPNS0_5MutexENS0_4TimeE"); __tsan_release(mu); bool r = f(this, mu, t); __tsan_acquire(mu); return r; }
}}
