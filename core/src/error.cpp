#include "lipsync/error.hpp"

#include <utility>

namespace lipsync {
namespace {

std::string located(const std::string& source, int line, const std::string& message) {
  std::string text = source;
  if (line > 0) {
    text.push_back(':');
    text.append(std::to_string(line));
  }
  if (!text.empty()) text.append(": ");
  text.append(message);
  return text;
}

}  // namespace

InputError::InputError(std::string source, int line, std::string message)
    : std::runtime_error(located(source, line, message)),
      source_(std::move(source)),
      line_(line),
      message_(std::move(message)) {}

}  // namespace lipsync
