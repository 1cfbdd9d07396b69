// A scrape of lipsyncd's Prometheus endpoint for tests: GET over a plain TCP
// socket, and a strict reader of the text exposition format (0.0.4) that fails
// the test on any line that is not a HELP, a TYPE or a sample of a declared family.
#pragma once

#include <gtest/gtest.h>
#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>

namespace lipsync::server::harness {

/// The body of GET `path` from http://`host_port`; "" with a test failure if no 200 came.
inline std::string http_get(const std::string& host_port, const std::string& path, int* status_out = nullptr) {
  const auto colon = host_port.rfind(':');
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (getaddrinfo(host_port.substr(0, colon).c_str(), host_port.substr(colon + 1).c_str(), &hints, &found) != 0) {
    ADD_FAILURE() << "cannot resolve " << host_port;
    return "";
  }
  const int fd = socket(found->ai_family, SOCK_STREAM, 0);
  const bool connected = connect(fd, found->ai_addr, found->ai_addrlen) == 0;
  freeaddrinfo(found);
  std::string response;
  if (connected) {
    const std::string request = "GET " + path + " HTTP/1.1\r\nHost: " + host_port + "\r\nConnection: close\r\n\r\n";
    [[maybe_unused]] const auto sent = send(fd, request.data(), request.size(), 0);
    char buffer[65536];
    for (ssize_t got; (got = recv(fd, buffer, sizeof(buffer), 0)) > 0;)
      response.append(buffer, static_cast<std::size_t>(got));
  }
  close(fd);
  const int status = response.size() > 12 ? std::stoi(response.substr(9, 3)) : 0;
  if (status_out) *status_out = status;
  const auto body = response.find("\r\n\r\n");
  return body == std::string::npos ? "" : response.substr(body + 4);
}

/// Samples by their series ("name{labels}" as written), and the declared families.
struct Exposition {
  std::map<std::string, double> samples;
  std::map<std::string, std::string> family_types;  ///< name → counter, gauge, histogram

  double at(const std::string& series) const {
    const auto found = samples.find(series);
    if (found == samples.end()) {
      ADD_FAILURE() << "no series " << series;
      return -1;
    }
    return found->second;
  }
  double value_or_zero(const std::string& series) const {
    const auto found = samples.find(series);
    return found == samples.end() ? 0 : found->second;
  }
};

/// Reads `text` as the Prometheus text format; every line that does not fit is a test failure.
inline Exposition parse_exposition(const std::string& text) {
  static const std::regex kHelp(R"(^# HELP ([a-zA-Z_:][a-zA-Z0-9_:]*) .*$)");
  static const std::regex kType(R"(^# TYPE ([a-zA-Z_:][a-zA-Z0-9_:]*) (counter|gauge|histogram|summary|untyped)$)");
  static const std::regex kSample(
      R"(^([a-zA-Z_:][a-zA-Z0-9_:]*)(\{[a-zA-Z_][a-zA-Z0-9_]*="(?:[^"\\\n]|\\.)*"(?:,[a-zA-Z_][a-zA-Z0-9_]*="(?:[^"\\\n]|\\.)*")*\})? (-?[0-9][0-9.e+-]*|\+Inf|-Inf|NaN)$)");
  Exposition exposition;
  std::istringstream lines(text);
  std::string line;
  int number = 0;
  while (std::getline(lines, line)) {
    ++number;
    std::smatch match;
    if (std::regex_match(line, match, kHelp)) continue;
    if (std::regex_match(line, match, kType)) {
      exposition.family_types[match[1]] = match[2];
      continue;
    }
    if (!std::regex_match(line, match, kSample)) {
      ADD_FAILURE() << "line " << number << " is not in the exposition format: " << line;
      continue;
    }
    std::string family = match[1];
    for (const char* suffix : {"_bucket", "_sum", "_count"}) {
      const std::string s = suffix;
      if (!exposition.family_types.count(family) && family.size() > s.size() &&
          family.compare(family.size() - s.size(), s.size(), s) == 0) {
        family.resize(family.size() - s.size());
      }
    }
    EXPECT_TRUE(exposition.family_types.count(family)) << "line " << number << ": no TYPE for " << family;
    const std::string value = match[3];
    exposition.samples[std::string(match[1]) + std::string(match[2])] = value == "+Inf"   ? 1e300
                                                                        : value == "-Inf" ? -1e300
                                                                                          : std::stod(value);
  }
  return exposition;
}

}  // namespace lipsync::server::harness
