#include "service/auth.h"

#include <openssl/evp.h>
#include <spdlog/fmt/fmt.h>
#include <sys/random.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <fstream>

#include "sim/demand.h"

namespace gd::service {

std::string random_hex(int bytes) {
  std::string raw(static_cast<size_t>(bytes), '\0');
  size_t got = 0;
  while (got < raw.size()) {
    const ssize_t n = getrandom(raw.data() + got, raw.size() - got, 0);
    if (n < 0 && errno == EINTR) continue;
    GD_DEMAND(n > 0, "getrandom failed: no entropy source for ids");
    got += static_cast<size_t>(n);
  }
  std::string hex;
  hex.reserve(2 * raw.size());
  for (unsigned char c : raw) hex += fmt::format("{:02x}", c);
  return hex;
}

std::string sha256_hex(const std::string& data) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  GD_DEMAND(EVP_Digest(data.data(), data.size(), md, &len, EVP_sha256(), nullptr) == 1, "SHA-256 failed");
  std::string hex;
  for (unsigned int i = 0; i < len; ++i) hex += fmt::format("{:02x}", md[i]);
  return hex;
}

std::string TokenSet::principal_of(const std::string& token) { return "t-" + sha256_hex(token).substr(0, 16); }

TokenSet TokenSet::load(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw sim::InputError(fmt::format("cannot read the token file '{}' (--auth-token-file)", path));
  TokenSet set;
  std::string line;
  int number = 0;
  while (std::getline(f, line)) {
    ++number;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto last = line.find_last_not_of(" \t\r");
    const std::string token = line.substr(first, last - first + 1);
    const bool printable = std::all_of(token.begin(), token.end(), [](char c) {
      return std::isgraph(static_cast<unsigned char>(c)) != 0;
    });
    if (!printable)
      throw sim::InputError(fmt::format("token file '{}', line {}: a token is one word of printable ASCII (no "
                                        "spaces or control characters)", path, number));
    if (token.size() < kMinLength)
      throw sim::InputError(fmt::format("token file '{}', line {}: a token needs at least {} characters (make one "
                                        "with: openssl rand -hex 32)", path, number, kMinLength));
    set.principals_[sha256_hex(token)] = principal_of(token);
  }
  if (set.principals_.empty())
    throw sim::InputError(fmt::format("the token file '{}' holds no token (one per line; make one with: openssl "
                                      "rand -hex 32)", path));
  return set;
}

std::string TokenSet::principal(const std::string& authorization) const {
  constexpr size_t kScheme = 7;  // "Bearer "
  if (authorization.size() <= kScheme) return "";
  std::string scheme = authorization.substr(0, kScheme);
  std::transform(scheme.begin(), scheme.end(), scheme.begin(), [](unsigned char c) { return std::tolower(c); });
  if (scheme != "bearer ") return "";
  auto it = principals_.find(sha256_hex(authorization.substr(kScheme)));
  return it == principals_.end() ? "" : it->second;
}

}  // namespace gd::service
