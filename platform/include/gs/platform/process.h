// SPDX-License-Identifier: MIT
// Running external programs (COLMAP, ffmpeg) without a shell: argv is passed as is, the child's
// stdout and stderr are merged, appended to a log file and handed line by line to a callback so
// the caller can show progress. Nothing is interpreted by /bin/sh, so paths with spaces are safe.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "gs/status.h"

namespace gs::platform {

// The absolute path of `program` found on PATH (or program itself when it contains a '/' and is
// executable); empty when there is none.
std::string find_program(const std::string& program);

struct ProcessResult {
  int exit_code = -1;  // the child's exit status; 128 + N when killed by signal N
  double seconds = 0;  // wall time
};

// Runs argv[0] with argv (argv[0] is looked up on PATH). Output lines (without the newline) go to
// on_line when set and are appended to log_path when it is not empty. Returns an error only when
// the program cannot be started or the log cannot be written; a non-zero exit is in the result.
Expected<ProcessResult> run_process(const std::vector<std::string>& argv, const std::string& log_path,
                                    const std::function<void(const std::string&)>& on_line = {});

}  // namespace gs::platform
