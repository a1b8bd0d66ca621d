#pragma once
/// \file
/// Shared by the libFuzzer targets of tests/fuzz (docs/fuzzing.md). A target feeds one input to a
/// parser of untrusted data; the outcomes it accepts are a parsed result and the project's input
/// error (sim::InputError, or a non-OK Status where the API returns one). Anything else is a
/// finding: a crash, a sanitizer report, a timeout, an out-of-memory, an exception of another type
/// (reported here with its type and message, then abort() so that libFuzzer keeps the input) or a
/// broken property of a parsed result (GD_FUZZ_CHECK).

#include <cxxabi.h>
#include <stdlib.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <typeinfo>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::fuzz {

/// Silences the project's logger (a run feeds it thousands of inputs a second); GD_LOG_LEVEL, as
/// everywhere, overrides it (e.g. GD_LOG_LEVEL=debug to see why one input is refused).
inline void quiet_logs() {
  if (!std::getenv("GD_LOG_LEVEL")) gd::log().set_level(spdlog::level::off);
}

/// A scratch directory of this process under $TMPDIR, removed at a normal exit (scripts/fuzz
/// points TMPDIR at a folder of its own in /dev/shm or its run directory and removes it at its end).
inline const std::string& scratch_dir() {
  // Never destroyed: the exit handler below runs after static destructors would have.
  static const std::string* dir = [] {
    auto* d = new std::string((std::filesystem::temp_directory_path() / "gd-fuzz-XXXXXX").string());
    if (!::mkdtemp(d->data())) {
      std::perror("gd-fuzz: mkdtemp");
      std::abort();
    }
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(*dir, ec);
    });
    return d;
  }();
  return *dir;
}

/// Writes the input to `name` in the scratch directory (the path-based readers take a file, and
/// decide by its extension); returns the path.
inline std::string write_input(const std::string& name, const uint8_t* data, size_t size) {
  const std::string path = scratch_dir() + "/" + name;
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  f.close();
  if (!f) {
    std::fprintf(stderr, "gd-fuzz: cannot write '%s'\n", path.c_str());
    std::abort();
  }
  return path;
}

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "\n==gd-fuzz== FINDING: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

inline std::string type_name(const std::type_info& t) {
  int status = 0;
  std::unique_ptr<char, void (*)(void*)> d(abi::__cxa_demangle(t.name(), nullptr, nullptr, &status), std::free);
  return status == 0 && d ? d.get() : t.name();
}

/// Runs `f`. Returns true when it returned, false when it threw sim::InputError (the expected
/// refusal of bad input); any other exception is a finding.
template <class F>
bool input_errors_only(F&& f) {
  try {
    f();
    return true;
  } catch (const gd::sim::InputError&) {
    return false;
  } catch (const std::exception& e) {
    fail("unexpected exception " + type_name(typeid(e)) + ": " + e.what());
  } catch (...) {
    fail("unexpected exception of a type not derived from std::exception");
  }
}

/// Runs `f`, which is not expected to throw at all (APIs that report errors as a Status).
template <class F>
void no_exceptions(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    fail("unexpected exception " + type_name(typeid(e)) + ": " + e.what());
  } catch (...) {
    fail("unexpected exception of a type not derived from std::exception");
  }
}

}  // namespace gd::fuzz

/// A property every successfully parsed result must have; a violation is a finding.
#define GD_FUZZ_CHECK(cond, msg)                                                                  \
  do {                                                                                            \
    if (!(cond)) ::gd::fuzz::fail(std::string("check failed: " #cond ": ") + std::string(msg));   \
  } while (0)
