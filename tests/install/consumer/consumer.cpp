// Renders three phonemes on the lipsyncd at argv[1] and streams them under a session, through the
// installed client library; prints "frames=N streamed=M" (exit 1 with the error otherwise).
#include <iostream>
#include <vector>

#include "lipsync/client/animation_client.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: consumer HOST:PORT\n";
    return 2;
  }
  try {
    lipsync::client::AnimationClient client(argv[1]);
    client.wait_connected();
    std::vector<lipsync::v1::Phoneme> phonemes;
    for (const auto& [label, start_us, end_us] :
         {std::tuple{"M", 0, 80'000}, {"AA", 80'000, 250'000}, {"P", 250'000, 330'000}}) {
      lipsync::v1::Phoneme phoneme;
      phoneme.set_label(label);
      phoneme.set_start_us(start_us);
      phoneme.set_end_us(end_us);
      phonemes.push_back(phoneme);
    }
    lipsync::v1::AnimationSettings settings;
    const auto rendered = client.render(settings, phonemes);
    settings.set_session("consumer");
    const std::vector<std::vector<lipsync::v1::Phoneme>> chunks = {phonemes};
    const auto streamed = client.animate(settings, chunks);
    std::cout << "frames=" << rendered.track.frame_count() << " streamed=" << streamed.track.frame_count() << "\n";
    return rendered.track.frame_count() > 0 && rendered.track.frame_count() == streamed.track.frame_count() ? 0 : 1;
  } catch (const std::exception& error) {
    std::cerr << "consumer: " << error.what() << "\n";
    return 1;
  }
}
