// SPDX-License-Identifier: MIT
// Names from data stay inside their folder (gs/platform/path.h), the folder lock refuses a second
// holder, and the fault-injection hook fails exactly the k-th write the way a disk does, leaving the
// old file.
#include <doctest/doctest.h>

#include <filesystem>
#include <string>

#include "gs/platform/file.h"
#include "gs/platform/path.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace gs::platform;

TEST_CASE("path: relative names from data may have sub-folders but never leave their folder") {
  CHECK(relative_name_problem("0001.png").empty());
  CHECK(relative_name_problem("cam1/0001.png").empty());
  CHECK(relative_name_problem("./a..b/..c.png").empty());  // dots inside a component are fine
  CHECK(relative_name_problem("") == "it is empty");
  CHECK(relative_name_problem("/etc/passwd") == "it is an absolute path");
  CHECK(relative_name_problem("../outside.png") == "it has a '..' component");
  CHECK(relative_name_problem("a/../../outside.png") == "it has a '..' component");
  CHECK(relative_name_problem("a/..") == "it has a '..' component");
  CHECK(relative_name_problem(std::string("a\0b", 3)) == "it contains a NUL byte");

  gs::test::TempDir dir("path");
  const std::string out = dir / "out";
  fs::create_directories(out);
  gs::Expected<std::string> ok = join_inside(out, "cam1/0001.png");
  REQUIRE(ok.ok());
  CHECK(*ok == out + "/cam1/0001.png");
  gs::Expected<std::string> up = join_inside(out, "../../outside.png");
  REQUIRE_FALSE(up.ok());
  CHECK(up.status().message() == "the name '../../outside.png' cannot be used below " + out + ": it has a '..' component");
  // A symbolic link inside the folder that points out of it is refused too.
  fs::create_directory_symlink(dir.path(), out + "/escape");
  gs::Expected<std::string> link = join_inside(out, "escape/x.png");
  REQUIRE_FALSE(link.ok());
  CHECK(link.status().message().find("through a symbolic link") != std::string::npos);

  CHECK(path_is_inside(out, out));
  CHECK(path_is_inside(out + "/a/b", out));
  CHECK(path_is_inside(out + "/not_yet/../a", out));
  CHECK_FALSE(path_is_inside(dir / "outer", out));
  CHECK_FALSE(path_is_inside(out + "2", out));  // a sibling sharing the prefix
  CHECK_FALSE(path_is_inside(out + "/escape/elsewhere", out));
}

TEST_CASE("file lock: a second holder is refused with the first one's pid until the first releases") {
  gs::test::TempDir dir("lock");
  gs::Expected<FileLock> first = FileLock::acquire(dir / ".lock", "folder X");
  REQUIRE(first.ok());
  gs::Expected<FileLock> second = FileLock::acquire(dir / ".lock", "folder X");
  REQUIRE_FALSE(second.ok());
  CHECK(second.status().message().find("folder X is in use by another hbgs process (pid ") == 0);
  *first = FileLock();
  CHECK(FileLock::acquire(dir / ".lock", "folder X").ok());
}

TEST_CASE("fault injection: the k-th write fails as a short write, ENOSPC or EIO and the old file stays") {
  gs::test::TempDir dir("fault");
  const std::string path = dir / "f.txt";
  REQUIRE(write_file_atomic(path, std::string("old content")).ok());
  const struct {
    WriteFault kind;
    const char* reason;
  } cases[] = {{WriteFault::kShortWrite, "No space left on device"},
               {WriteFault::kNoSpace, "No space left on device"},
               {WriteFault::kIoError, "Input/output error"}};
  for (const auto& c : cases) {
    inject_write_fault(2, c.kind);
    CHECK(write_file_atomic(dir / "first.txt", std::string("fine")).ok());  // write 1 passes
    const gs::Status st = write_file_atomic(path, std::string("new content that does not fit"));
    CHECK(write_file_atomic(dir / "third.txt", std::string("fine")).ok());  // only the k-th fails
    CHECK(write_file_atomic_calls() == 3);
    inject_write_fault(0, c.kind);
    REQUIRE_FALSE(st.ok());
    CHECK_MESSAGE(st.message().find(c.reason) != std::string::npos, st.message());
    gs::Expected<std::string> now = read_text_file(path);
    REQUIRE(now.ok());
    CHECK(*now == "old content");
    for (const auto& e : fs::directory_iterator(dir.path())) CHECK(e.path().filename().string().find(".tmp.") == std::string::npos);
  }
}
