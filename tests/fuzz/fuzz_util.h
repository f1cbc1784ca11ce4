// Shared helpers of the libFuzzer targets (tests/fuzz/*_fuzzer.cc).
//
// Contract of every target: LLVMFuzzerTestOneInput hands the bytes to a public
// lisfm reader (in memory or through a file) and returns 0. A clean rejection
// of bad input -- lisfm::InputError -- is caught by the target; anything else
// (another exception, a crash, a sanitizer report, a hang) escapes and is a bug.
// The same entry points run in the normal build through replay_corpus.cc.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace lisfm::fuzz {

// A folder of this process under $TMPDIR (or /tmp), created on first use and
// removed at exit. Thread safety: none (libFuzzer runs one input at a time).
const std::string& ScratchDir();

// Writes `size` bytes to ScratchDir()/<name> (replacing it) and returns the path.
std::string WriteScratchFile(const std::string& name, const uint8_t* data, size_t size);

// Removes ScratchDir()/<name> and everything below it (no error when absent).
void RemoveScratch(const std::string& name);

}  // namespace lisfm::fuzz

// libFuzzer's optional initialisation hook (the replay driver calls it too):
// silences the logging facade, so that a run measures the readers, not the terminal.
extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv);
