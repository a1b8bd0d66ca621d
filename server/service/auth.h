#pragma once
/// \file
/// The service's security primitives: unguessable ids (random_hex, from the kernel's CSPRNG) and
/// bearer tokens (TokenSet, loaded from --auth-token-file). A caller is known by its token's
/// principal, "t-" and the first 16 hex digits of the token's SHA-256: stable across restarts and
/// reorderings of the file, stored with the caller's jobs, never the token itself. No gRPC types.

#include <map>
#include <string>

namespace gd::service {

/// `bytes` random bytes from getrandom(2) as 2 x bytes lowercase hex digits. Aborts (an
/// invariant) if the kernel has no entropy source, which Linux always has.
std::string random_hex(int bytes);

/// Lowercase hex SHA-256 of `data`.
std::string sha256_hex(const std::string& data);

/// The tokens a server accepts.
class TokenSet {
 public:
  /// Shortest token accepted, characters: a token is a secret, not a password to remember.
  static constexpr size_t kMinLength = 16;

  TokenSet() = default;
  /// Reads FILE: one token per line, surrounding whitespace stripped, blank lines and lines
  /// starting with '#' ignored. Throws sim::InputError naming the file and the line for an
  /// unreadable or empty file, a token shorter than kMinLength or with spaces or control
  /// characters.
  static TokenSet load(const std::string& path);

  /// Whether tokens are required (a file was loaded).
  bool enabled() const { return !principals_.empty(); }
  size_t size() const { return principals_.size(); }

  /// The principal of the bearer token in an "authorization" metadata value ("Bearer TOKEN",
  /// scheme case-insensitive), or "" when it is missing, malformed or unknown. Lookup is by the
  /// token's hash, so the comparison time does not depend on how much of a guess was right.
  std::string principal(const std::string& authorization) const;

  /// The principal a token maps to (whether or not it is in the set).
  static std::string principal_of(const std::string& token);

 private:
  std::map<std::string, std::string> principals_;  ///< SHA-256 hex of a token -> its principal
};

}  // namespace gd::service
