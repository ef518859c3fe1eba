// A driver for the fuzz targets without libFuzzer, for any compiler (the
// CI's g++ ASan + UBSan build; BANMO_FUZZ_SMOKE, tools/run_sanitizer_tests.sh):
// runs the target's LLVMFuzzerTestOneInput on every file of the corpus
// folders, then on random mutations of them (bit flips, byte and integer
// overwrites, insertions, deletions, truncations, splices of two inputs)
// until -max_total_time seconds have passed. It is not coverage-guided: a
// smoke test of every parser on damaged input under the sanitizers. The
// coverage-guided campaign is tools/run_fuzz.sh (libFuzzer, clang).
//   fuzz_npy_smoke -max_total_time=10 [-seed=1] [-max_len=N] CORPUS_DIR...
// A finding aborts (sanitizer report, CHECK failure, fuzz::Expect); the
// input that caused it is first written to ./smoke-crash-<pid> (replay it
// with the libFuzzer target or with this driver given the file).
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
// Provided by ASan (gcc and clang; weak: absent without it): the callback
// runs before a report ends the process.
extern "C" __attribute__((weak)) void __sanitizer_set_death_callback(void (*callback)(void));

namespace {

// The input being run, for the crash handlers (written, never freed).
const std::string* g_current = nullptr;

void SaveCurrentInput() {
  if (g_current == nullptr) return;
  char name[64];
  std::snprintf(name, sizeof(name), "smoke-crash-%d", static_cast<int>(::getpid()));
  const int fd = ::open(name, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) return;
  const char* p = g_current->data();
  size_t left = g_current->size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n <= 0) break;
    p += n;
    left -= static_cast<size_t>(n);
  }
  ::close(fd);
  static const char kNote[] = "fuzz smoke: the input is in ./smoke-crash-<pid>\n";
  [[maybe_unused]] const ssize_t w = ::write(2, kNote, sizeof(kNote) - 1);
}

void OnSignal(int sig) {
  SaveCurrentInput();
  ::signal(sig, SIG_DFL);
  ::raise(sig);
}

void Run(const std::string& input) {
  g_current = &input;
  LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(input.data()), input.size());
  g_current = nullptr;
}

std::vector<std::string> ReadCorpus(const std::vector<std::string>& paths) {
  namespace fs = std::filesystem;
  std::vector<std::string> files;
  for (const std::string& p : paths) {
    std::error_code ec;
    if (fs::is_directory(p, ec)) {
      for (const auto& e : fs::recursive_directory_iterator(p, ec)) {
        if (e.is_regular_file(ec)) files.push_back(e.path().string());
      }
    } else if (fs::is_regular_file(p, ec)) {
      files.push_back(p);
    } else {
      std::fprintf(stderr, "fuzz smoke: %s: not a file or folder\n", p.c_str());
      std::exit(2);
    }
  }
  std::vector<std::string> corpus;
  for (const std::string& f : files) {
    std::ifstream in(f, std::ios::binary);
    corpus.emplace_back(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  return corpus;
}

// One to four random edits of `s` (libFuzzer's simpler mutations).
std::string Mutate(std::string s, const std::vector<std::string>& corpus, size_t max_len,
                   std::mt19937_64& rng) {
  auto below = [&rng](size_t n) { return n == 0 ? size_t{0} : static_cast<size_t>(rng() % n); };
  static const uint64_t kInteresting[] = {0,          1,          0x7f,        0x80,
                                          0xff,       0x7fff,     0x8000,      0xffff,
                                          0x7fffffff, 0x80000000, 0xffffffff,  0xffffffffffffffff,
                                          16384,      16385,      0x100000000, 1000000};
  const int edits = 1 + static_cast<int>(below(4));
  for (int k = 0; k < edits; ++k) {
    switch (below(8)) {
      case 0:  // flip a bit
        if (!s.empty()) s[below(s.size())] ^= static_cast<char>(1u << below(8));
        break;
      case 1:  // random byte
        if (!s.empty()) s[below(s.size())] = static_cast<char>(below(256));
        break;
      case 2: {  // interesting integer, 1-8 bytes little-endian
        if (s.empty()) break;
        const uint64_t v = kInteresting[below(std::size(kInteresting))];
        const size_t at = below(s.size());
        const size_t n = std::min<size_t>(1 + below(8), s.size() - at);
        for (size_t i = 0; i < n; ++i) s[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
        break;
      }
      case 3: {  // insert random bytes
        const size_t n = 1 + below(16);
        std::string bytes(n, '\0');
        for (char& c : bytes) c = static_cast<char>(below(256));
        s.insert(below(s.size() + 1), bytes);
        break;
      }
      case 4:  // delete a range
        if (!s.empty()) {
          const size_t at = below(s.size());
          s.erase(at, 1 + below(std::min<size_t>(64, s.size() - at)));
        }
        break;
      case 5:  // truncate
        if (!s.empty()) s.resize(below(s.size()));
        break;
      case 6: {  // splice: a piece of another corpus input
        const std::string& other = corpus[below(corpus.size())];
        if (other.empty()) break;
        const size_t from = below(other.size());
        const size_t n = 1 + below(std::min<size_t>(256, other.size() - from));
        s.insert(below(s.size() + 1), other.substr(from, n));
        break;
      }
      case 7: {  // duplicate a range
        if (s.empty()) break;
        const size_t from = below(s.size());
        const size_t n = 1 + below(std::min<size_t>(64, s.size() - from));
        s.insert(below(s.size() + 1), s.substr(from, n));
        break;
      }
    }
  }
  if (s.size() > max_len) s.resize(max_len);
  return s;
}

bool Flag(const char* arg, const char* name, long long* value) {
  const size_t n = std::strlen(name);
  if (std::strncmp(arg, name, n) != 0 || arg[n] != '=') return false;
  char* end = nullptr;
  *value = std::strtoll(arg + n + 1, &end, 10);
  if (end == arg + n + 1 || *end != '\0' || *value < 0) {
    std::fprintf(stderr, "fuzz smoke: %s: expected a number >= 0\n", arg);
    std::exit(2);
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  long long seconds = 10, seed = 1, max_len = 1 << 20;
  std::vector<std::string> paths;
  for (int i = 1; i < argc; ++i) {
    if (Flag(argv[i], "-max_total_time", &seconds) || Flag(argv[i], "-seed", &seed) ||
        Flag(argv[i], "-max_len", &max_len)) {
      continue;
    }
    if (argv[i][0] == '-') {
      std::fprintf(stderr, "fuzz smoke: unknown flag %s\n", argv[i]);
      return 2;
    }
    paths.emplace_back(argv[i]);
  }
  if (paths.empty()) {
    std::fprintf(stderr,
                 "usage: %s -max_total_time=S [-seed=N] [-max_len=N] CORPUS_DIR_OR_FILE...\n",
                 argv[0]);
    return 2;
  }
  if (__sanitizer_set_death_callback != nullptr) {
    __sanitizer_set_death_callback(SaveCurrentInput);
  }
  ::signal(SIGABRT, OnSignal);
  ::signal(SIGSEGV, OnSignal);
  ::signal(SIGFPE, OnSignal);

  const std::vector<std::string> corpus = ReadCorpus(paths);
  const auto start = std::chrono::steady_clock::now();
  long long runs = 0;
  for (const std::string& input : corpus) {
    Run(input);
    ++runs;
  }
  const long long corpus_runs = runs;
  std::mt19937_64 rng(static_cast<uint64_t>(seed));
  const std::string empty;
  const auto deadline = start + std::chrono::seconds(seconds);
  while (std::chrono::steady_clock::now() < deadline) {
    const std::string& base = corpus.empty() ? empty : corpus[rng() % corpus.size()];
    Run(Mutate(base, corpus, static_cast<size_t>(max_len), rng));
    ++runs;
  }
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("fuzz smoke %s: %lld executions (%lld corpus inputs, %lld mutated) in %.1f s\n",
              std::filesystem::path(argv[0]).filename().c_str(), runs, corpus_runs,
              runs - corpus_runs, elapsed);
  return 0;
}
