// Happens-before edges that gRPC's callback API guarantees, stated for
// ThreadSanitizer; used by the server's reactors and the client library's.
// Debian's gRPC and abseil are not compiled with TSan, so the synchronisation
// by which gRPC hands a reactor from one of its threads to another (its
// completion queues, abseil's Mutex, atomics) is invisible, and every field a
// reactor touches in two reactions looks raced (docs/security.md,
// "Sanitizers"). Each edge below is one promise of the API, and nothing more:
//
// - An operation started on a reactor (StartCall, StartSendInitialMetadata,
//   StartRead, StartWrite, StartWritesDone, Finish) happens before the
//   reaction that reports its completion: what the reactor wrote before
//   starting it is visible there. HandoffReactor releases the reactor before
//   each of them, and a reaction acquires it on entry (HandoffScope). The same
//   for RemoveHold, after which gRPC may run OnDone on another thread.
// - StartRead(message) happens before gRPC parses the next message into
//   `message`, on whichever thread completes the read: StartRead releases the
//   message too. The parse is protobuf's (uninstrumented) code called from
//   gRPC's; the library `deploy/sanitize.sh tsan` preloads
//   (deploy/sanitizers/tsan_edges.cpp) acquires the message when protobuf starts
//   parsing into it and releases it when the parse returns.
// - The method handler returns the reactor to gRPC, which runs its reactions
//   later, on its own threads: the handler releases it once built (handed_off).
// - Reactions of one reactor never overlap, and OnDone comes after all the
//   others have returned: a reaction releases the reactor on exit too.
// - The service is built before the server starts, and gRPC calls its method
//   handlers only after that (on its threads, created by libgpr, whose
//   pthread_create TSan ignores: deploy/sanitizers/tsan.supp): Server releases the
//   service before BuildAndStart and once its address is known, and each
//   method handler acquires it on entry.
// - gRPC's Server::Shutdown returns only after every call's OnDone has (it
//   waits for each call's request, which gRPC deletes once OnDone returns),
//   calls refused during the drain included: each OnDone ends by releasing the
//   service's own key (LipSyncService::call_ended), and Server acquires it
//   after Shutdown, before it destroys the service.
//
// Under -fsanitize=thread (GCC defines `__SANITIZE_THREAD__`, clang 14
// answers `__has_feature(thread_sanitizer)`) these call the TSan runtime's
// __tsan_release / __tsan_acquire; in every other build they are empty inline
// functions and compile to nothing.
#pragma once

#include <utility>

#if defined(__SANITIZE_THREAD__)
#define LIPSYNC_TSAN_HANDOFF 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define LIPSYNC_TSAN_HANDOFF 1
#endif
#endif

#if defined(LIPSYNC_TSAN_HANDOFF)
extern "C" void __tsan_acquire(void* address);
extern "C" void __tsan_release(void* address);
#endif

namespace lipsync {

/// Publishes what this thread wrote so far to the thread that next acquires `object`.
inline void handoff_release(const void* object) {
#if defined(LIPSYNC_TSAN_HANDOFF)
  __tsan_release(const_cast<void*>(object));
#else
  (void)object;
#endif
}

/// Sees what the threads that released `object` wrote before they did.
inline void handoff_acquire(const void* object) {
#if defined(LIPSYNC_TSAN_HANDOFF)
  __tsan_acquire(const_cast<void*>(object));
#else
  (void)object;
#endif
}

/// A reaction's whole body: acquires the reactor on entry, releases it on exit.
class HandoffScope {
 public:
  explicit HandoffScope(const void* reactor) : reactor_(reactor) { handoff_acquire(reactor_); }
  ~HandoffScope() { handoff_release(reactor_); }
  HandoffScope(const HandoffScope&) = delete;
  HandoffScope& operator=(const HandoffScope&) = delete;

 private:
  const void* reactor_;
};

/// A gRPC reactor (`Reactor`: ServerBidiReactor<...>, ServerWriteReactor<...>,
/// ServerUnaryReactor, ClientBidiReactor<...>, ClientReadReactor<...>) whose operations
/// release it before gRPC takes them over. The names hide the base's, so a reactor
/// derived from this calls them unchanged (each is instantiated only where used).
/// Reactions open with `const HandoffScope handoff = reaction();`, OnDone with
/// `last_reaction();`.
template <class Reactor>
class HandoffReactor : public Reactor {
 protected:
  // gRPC's own names: each hides the reactor's operation of that name.
  // NOLINTBEGIN(readability-identifier-naming)
  template <class... Arguments>
  void StartCall(Arguments&&... arguments) {
    handoff_release(key());
    Reactor::StartCall(std::forward<Arguments>(arguments)...);
  }
  template <class... Arguments>
  void StartSendInitialMetadata(Arguments&&... arguments) {
    handoff_release(key());
    Reactor::StartSendInitialMetadata(std::forward<Arguments>(arguments)...);
  }
  template <class Message>
  void StartRead(Message* message) {
    handoff_release(key());
    handoff_release(message);
    Reactor::StartRead(message);
  }
  template <class... Arguments>
  void StartWritesDone(Arguments&&... arguments) {
    handoff_release(key());
    Reactor::StartWritesDone(std::forward<Arguments>(arguments)...);
  }
  template <class... Arguments>
  void RemoveHold(Arguments&&... arguments) {
    handoff_release(key());
    Reactor::RemoveHold(std::forward<Arguments>(arguments)...);
  }
  template <class... Arguments>
  void StartWrite(Arguments&&... arguments) {
    handoff_release(key());
    Reactor::StartWrite(std::forward<Arguments>(arguments)...);
  }
  template <class... Arguments>
  void Finish(Arguments&&... arguments) {
    handoff_release(key());
    Reactor::Finish(std::forward<Arguments>(arguments)...);
  }
  // NOLINTEND(readability-identifier-naming)

  /// The scope of one reaction (OnReadDone, OnWriteDone, OnCancel, ...).
  [[nodiscard]] HandoffScope reaction() const { return HandoffScope(key()); }
  /// The entry of OnDone, which comes after every other reaction and deletes the
  /// reactor (no release on exit: the address may be another reactor's by then).
  void last_reaction() const { handoff_acquire(key()); }

 public:
  /// For the method handler, once the reactor is built: gRPC runs its reactions later.
  void handed_off() const { handoff_release(key()); }

 private:
  const void* key() const { return static_cast<const Reactor*>(this); }
};

}  // namespace lipsync
