/* Preloaded into `volpar run` by tests/tools/kill_sweep.py: counts the process's pwrite calls (HDF5's sec2
 * driver writes only with pwrite) and sends the process SIGKILL just before the one numbered
 * $VOLPAR_KILL_AT_WRITE, so a run can be killed between any two of its writes. With $VOLPAR_COUNT_WRITES
 * naming a file, the count so far is kept there (eight bytes, native order) after every write. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

typedef ssize_t (*pwrite_fn)(int, const void*, size_t, off_t);

static pwrite_fn real_pwrite;
static int64_t written;
static int64_t kill_at = -1;
static int count_fd = -1;

static void start(void) {
  if (real_pwrite) return;
  void* next = dlsym(RTLD_NEXT, "pwrite64");
  memcpy(&real_pwrite, &next, sizeof real_pwrite); /* (ISO C has no cast from object to function pointer) */
  const char* at = getenv("VOLPAR_KILL_AT_WRITE");
  if (at) kill_at = strtoll(at, NULL, 10);
  const char* count = getenv("VOLPAR_COUNT_WRITES");
  if (count) count_fd = open(count, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
}

static ssize_t counted(int fd, const void* buf, size_t n, off_t at) {
  start();
  if (++written == kill_at) kill(getpid(), SIGKILL);
  const ssize_t r = real_pwrite(fd, buf, n, at);
  if (count_fd >= 0 && fd != count_fd) (void)real_pwrite(count_fd, &written, sizeof written, 0);
  return r;
}

ssize_t pwrite(int fd, const void* buf, size_t n, off_t at) { return counted(fd, buf, n, at); }
ssize_t pwrite64(int fd, const void* buf, size_t n, off_t at) { return counted(fd, buf, n, at); }
