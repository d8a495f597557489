// SPDX-License-Identifier: MIT
// The committed state of a training run folder, so that model.hbgs, checkpoint.bin and
// progress.json always describe the same iteration whatever fails, and two processes never write one
// folder.
//
// A commit writes the state files under "<name>.next", then manifest.json (the commit point: the
// iteration, the model options and dataset the state belongs to, and each file's size and FNV-1a
// checksum), then renames the ".next" files into place. A failure before the manifest leaves the
// previous state untouched; a crash among the renames is completed by recover_run_state, which
// every writer of the folder calls first (under the folder's lock).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "gs/platform/file.h"
#include "gs/status.h"

namespace gs::jobs {

inline constexpr const char* kManifestFile = "manifest.json";
inline constexpr const char* kRunLockFile = ".hbgs.lock";
inline constexpr const char* kNextSuffix = ".next";

// Takes the run folder's lock (the folder must exist); fails at once when another process holds it.
Expected<platform::FileLock> lock_run_folder(const std::string& run);

struct RunStateFile {
  std::string name;  // inside the run folder
  uint64_t bytes = 0, fnv1a64 = 0;
};

struct RunState {
  bool committed = false;    // manifest.json exists (and every file it lists matches it)
  int iteration = 0;         // of the committed state
  std::string dataset;       // absolute dataset folder the state was trained on
  std::string model_options; // JSON text of the model options the state was made with
  std::vector<RunStateFile> files;
  std::vector<std::string> notes;  // what recovery did (an interrupted commit completed, stale files removed)
};

// Reads manifest.json, completes an interrupted commit (renames ".next" files whose checksum the
// manifest lists), removes stale ".next" files and atomic-write temporaries, and verifies every
// listed file. Errors name the file that does not match and what to do. No manifest: committed false.
Expected<RunState> recover_run_state(const std::string& run);

// Commits the files "<run>/<name>.next" (already written) as the state at `iteration`.
Status commit_run_state(const std::string& run, int iteration, const std::string& dataset,
                        const std::string& model_options, const std::vector<std::string>& names);

// Verifies without changing anything that the folder is at a committed state: the manifest parses,
// every listed file matches it, and no ".next" file or atomic-write temporary is left. For tests
// and for users who want to check a folder after a failure.
Expected<RunState> check_run_state(const std::string& run);

}  // namespace gs::jobs
