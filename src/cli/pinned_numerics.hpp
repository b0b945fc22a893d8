/// \file
/// One seed, one result on every x86-64 machine: the floating-point code that libraries pick by the CPU at run time,
/// pinned to the x86-64 baseline before a program computes anything. Programs only (docs/ARCHITECTURE.md,
/// "Reproducible across machines").
///
/// Two libraries this project's results pass through choose their code when the process starts:
/// - glibc's libm takes FMA variants of exp, log, pow, sin, cos, tan, atan, atan2 (and FMA4 ones on old AMD CPUs)
///   when the CPU has FMA. They round differently from the baseline ones in the last bit for some arguments, and a
///   rollout with contacts turns one bit into another fold (the fold's demonstration: q 0.534 with FMA, 0.536
///   without). glibc reads its tunables only at start: GLIBC_TUNABLES=glibc.cpu.hwcaps=-FMA,-FMA4 masks them.
/// - OpenCV dispatches SSE4.1 ... AVX-512 kernels (the reward's image filters among them): the (7.52) depth gradient
///   moved in its 8th digit with them masked. OPENCV_CPU_DISABLE, also read at load time, masks them.
/// So a program that finds either unmasked executes itself again once (/proc/self/exe, the same arguments) with
/// both set. A fold rollout costs the same (0.66 s against 0.69 s median over make demo's 208 rollouts).
///
/// A third choice is Eigen's: it asks the CPU for its cache sizes and blocks its matrix products by them, and the
/// blocking sets the order in which a long product is summed. An AMD EPYC (32 KiB, 512 KiB, 32 MiB) and an Intel Xeon
/// (48 KiB, 2 MiB, 105 MiB) gave other first policies to make demo's learning from the same seed. Eigen takes the
/// sizes it is given at any time (Eigen::setCpuCacheSizes): a program sets those of the Intel Xeon its committed
/// results were measured on.
#pragma once

#if defined(__x86_64__)
#include <sys/platform/x86.h>
#endif
#include <unistd.h>

#include <Eigen/Core>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace bimanual_skills::cli {

/// The glibc tunable, and its value that keeps libm on its baseline x86-64 code.
inline constexpr const char* kHwcapsTunable = "glibc.cpu.hwcaps=";
inline constexpr const char* kLibmMask = "-FMA,-FMA4";
/// The kernels Debian's OpenCV dispatches beyond its SSE2 baseline (cv::getCPUFeaturesLine()'s starred ones) that
/// this CPU has: OpenCV warns of a feature it is asked to disable and does not have.
inline std::string openCvMask() {
  std::string mask;
#if defined(__x86_64__)
  const auto add = [&mask](bool active, const char* name) {
    if (active) mask += std::string(mask.empty() ? "" : ",") + name;
  };
  add(CPU_FEATURE_ACTIVE(SSE4_1), "SSE4.1");
  add(CPU_FEATURE_ACTIVE(SSE4_2), "SSE4.2");
  add(CPU_FEATURE_ACTIVE(F16C), "FP16");
  add(CPU_FEATURE_ACTIVE(AVX), "AVX");
  add(CPU_FEATURE_ACTIVE(AVX2), "AVX2");
  add(CPU_FEATURE_ACTIVE(AVX512F) && CPU_FEATURE_ACTIVE(AVX512CD) && CPU_FEATURE_ACTIVE(AVX512BW) &&
          CPU_FEATURE_ACTIVE(AVX512DQ) && CPU_FEATURE_ACTIVE(AVX512VL),
      "AVX512-SKX");
#endif
  return mask;
}
/// Set in the re-executed process, so that a mask glibc ignores (a secure-execution process) cannot loop.
inline constexpr const char* kPinnedMarker = "BIMANUAL_SKILLS_NUMERICS_PINNED";

/// Whether glibc's libm runs its baseline code in this process (neither FMA nor FMA4 active). Always true off x86-64,
/// where there is nothing of this kind to pin.
inline bool libmPinned() noexcept {
#if defined(__x86_64__)
  return !CPU_FEATURE_ACTIVE(FMA) && !CPU_FEATURE_ACTIVE(FMA4);
#else
  return true;
#endif
}

/// The cache sizes Eigen blocks its products by in a program: those the committed results' Intel Xeon reported.
inline constexpr std::ptrdiff_t kEigenCaches[3] = {48 * 1024, 2 * 1024 * 1024, 105 * 1024 * 1024};

/// Whether Eigen blocks its products by kEigenCaches in this process.
inline bool eigenPinned() noexcept {
  return Eigen::l1CacheSize() == kEigenCaches[0] && Eigen::l2CacheSize() == kEigenCaches[1] &&
         Eigen::l3CacheSize() == kEigenCaches[2];
}

/// Whether OpenCV was told at load time to keep to its baseline kernels (OPENCV_CPU_DISABLE names openCvMask()).
inline bool openCvPinned() {
  const std::string mask = openCvMask();
  if (mask.empty()) return true;
  const char* value = std::getenv("OPENCV_CPU_DISABLE");
  return value != nullptr && std::strstr(value, mask.c_str()) != nullptr;
}

/// "pinned" when libm, OpenCV and Eigen are, else what is not (for a program's summary.json and log).
inline std::string numericsState() {
  if (libmPinned() && openCvPinned() && eigenPinned()) return "pinned";
  std::string state = "not pinned:";
  const auto add = [&state](bool pinned, const char* what) {
    if (!pinned) state += std::string(state.back() == ':' ? " " : ", ") + what;
  };
  add(libmPinned(), "libm's FMA code active");
  add(openCvPinned(), "OpenCV's dispatched kernels active");
  add(eigenPinned(), "Eigen blocks by this CPU's caches");
  return state;
}

/// Call first in main(), before anything computes: sets Eigen's cache sizes, then returns at once when libm and OpenCV
/// are pinned; otherwise adds the masks to the environment (keeping the caller's GLIBC_TUNABLES and
/// OPENCV_CPU_DISABLE entries) and executes the program again with the same arguments, so it does not return. It
/// returns, with a warning on stderr, when that is not possible or did not take: under valgrind (which would not
/// follow; set both variables for it), when exec fails, or when the re-executed process still finds a mask ignored.
/// argv is main()'s.
inline void pinNumerics(char** argv) {
  Eigen::setCpuCacheSizes(kEigenCaches[0], kEigenCaches[1], kEigenCaches[2]);
  if (libmPinned() && openCvPinned()) return;
  const auto warn = [](const std::string& why) {
    std::fprintf(stderr, "%s: numerics not pinned (%s): results may differ in the last bits from other machines'\n",
                 program_invocation_short_name, why.c_str());
  };
  if (std::getenv(kPinnedMarker) != nullptr) {
    warn(numericsState() + " after re-executing with GLIBC_TUNABLES and OPENCV_CPU_DISABLE set");
    return;
  }
  const char* preload = std::getenv("LD_PRELOAD");
  if (preload != nullptr && std::strstr(preload, "vgpreload") != nullptr) {
    warn(std::string("running under valgrind; set GLIBC_TUNABLES=") + kHwcapsTunable + kLibmMask +
         " OPENCV_CPU_DISABLE=" + openCvMask());
    return;
  }
  if (!libmPinned()) {
    // A caller's glibc.cpu.hwcaps entry gets the masks (glibc would keep one of two entries); else it is appended.
    const char* old = std::getenv("GLIBC_TUNABLES");
    std::string tunables = old != nullptr ? old : "";
    const std::size_t entry = tunables.find(kHwcapsTunable);
    if (entry != std::string::npos) {
      tunables.insert(entry + std::strlen(kHwcapsTunable), std::string(kLibmMask) + ",");
    } else {
      tunables += std::string(tunables.empty() ? "" : ":") + kHwcapsTunable + kLibmMask;
    }
    setenv("GLIBC_TUNABLES", tunables.c_str(), 1);
  }
  if (!openCvPinned()) {
    const char* old = std::getenv("OPENCV_CPU_DISABLE");
    const std::string masks = old != nullptr && *old != '\0' ? std::string(old) + "," + openCvMask() : openCvMask();
    setenv("OPENCV_CPU_DISABLE", masks.c_str(), 1);
  }
  setenv(kPinnedMarker, "1", 1);
  execv("/proc/self/exe", argv);
  warn(std::string("cannot execute /proc/self/exe again: ") + std::strerror(errno));
}

}  // namespace bimanual_skills::cli
