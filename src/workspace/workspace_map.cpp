#include "bimanual_skills/workspace/workspace_map.hpp"

#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/parallel/parallel_for.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>

namespace bimanual_skills::workspace {

namespace {

using kinematics::ChainData;
using kinematics::ChainModel;

constexpr double kCoincident = 1e-6;    ///< [m] Axes closer than this meet.
constexpr double kNoTimeBudget = 60.0;  ///< [s] The IK's time budget: never the limit (the attempts are).

Eigen::Vector3d axisOrigin(const ChainData& d, int i) {
  return d.axis_frames[static_cast<std::size_t>(i)].translation();
}
Eigen::Vector3d axisDirection(const ChainData& d, int i) {
  return d.axis_frames[static_cast<std::size_t>(i)].linear().col(2);
}

/// The point nearest to the lines of joints i and j (the middle of their common perpendicular); false if parallel.
bool meet(const ChainData& d, int i, int j, Eigen::Vector3d& point) {
  const Eigen::Vector3d a = axisOrigin(d, i), u = axisDirection(d, i), b = axisOrigin(d, j), v = axisDirection(d, j);
  const double uv = u.dot(v), denominator = 1.0 - uv * uv;
  if (denominator < 1e-12) return false;
  const Eigen::Vector3d w = a - b;
  const double s = (uv * v.dot(w) - u.dot(w)) / denominator, t = (v.dot(w) - uv * u.dot(w)) / denominator;
  point = 0.5 * ((a + s * u) + (b + t * v));
  return true;
}

double distanceToAxis(const ChainData& d, int i, const Eigen::Vector3d& p) {
  const Eigen::Vector3d r = p - axisOrigin(d, i);
  return (r - r.dot(axisDirection(d, i)) * axisDirection(d, i)).norm();
}

/// The point where joints i, i + 1 and i + 2 meet, if they do.
bool sphericalJoint(const ChainData& d, int i, Eigen::Vector3d& point) {
  return meet(d, i, i + 1, point) && distanceToAxis(d, i, point) < kCoincident &&
         distanceToAxis(d, i + 1, point) < kCoincident && distanceToAxis(d, i + 2, point) < kCoincident;
}

Eigen::VectorXd midLimits(const ChainModel& model) {
  Eigen::VectorXd q(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    const double lo = model.lowerLimits()[i], hi = model.upperLimits()[i];
    q[i] = std::isfinite(lo) && std::isfinite(hi) ? 0.5 * (lo + hi) : 0.0;
  }
  return q;
}

void forward(const ChainModel& model, ChainData& data, const Eigen::VectorXd& q) {
  if (kinematics::forwardKinematics(model, data, q) != kinematics::KinematicsStatus::Success) {
    throw std::invalid_argument("workspace map: forward kinematics failed");
  }
}

/// The reach test of an arm with a spherical shoulder (joints 0–2), one elbow joint and a spherical wrist (the last
/// three joints): the shoulder centre (fixed in the base), the wrist centre in the tool frame, and the range of their
/// distance over the elbow's limits.
struct WristReach {
  bool valid = false;
  Eigen::Vector3d shoulder = Eigen::Vector3d::Zero();
  Eigen::Vector3d wrist_in_tool = Eigen::Vector3d::Zero();
  double min = 0.0, max = 0.0;

  static WristReach of(const ChainModel& model, int forearm) {
    WristReach r;
    const int n = model.nq();
    if (n != 7 || forearm != 4) return r;
    ChainData data(model);
    std::mt19937 rng(7);
    Eigen::Vector3d shoulder, wrist;
    forward(model, data, midLimits(model));
    if (!sphericalJoint(data, 0, shoulder) || !sphericalJoint(data, forearm, wrist)) return r;
    const Eigen::Vector3d in_tool = data.tipPose().inverse() * wrist;
    for (int k = 0; k < 20; ++k) {  // both centres must stay put where the definition says
      forward(model, data, kinematics::randomWithinLimits(model, rng));
      Eigen::Vector3d s, w;
      if (!sphericalJoint(data, 0, s) || !sphericalJoint(data, forearm, w)) return r;
      if ((s - shoulder).norm() > kCoincident || (data.tipPose().inverse() * w - in_tool).norm() > kCoincident)
        return r;
    }
    const double elbow_lower = model.lowerLimits()[3], elbow_upper = model.upperLimits()[3];
    if (!std::isfinite(elbow_lower) || !std::isfinite(elbow_upper)) return r;
    Eigen::VectorXd q = midLimits(model);
    r.min = std::numeric_limits<double>::infinity();
    r.max = 0.0;
    double step = 0.0, previous = -1.0;
    constexpr int kSamples = 4001;
    for (int k = 0; k < kSamples; ++k) {
      q[3] = elbow_lower + (elbow_upper - elbow_lower) * k / (kSamples - 1);
      forward(model, data, q);
      Eigen::Vector3d w;
      if (!sphericalJoint(data, forearm, w)) return r;
      const double distance = (w - shoulder).norm();
      r.min = std::min(r.min, distance);
      r.max = std::max(r.max, distance);
      if (previous >= 0.0) step = std::max(step, std::abs(distance - previous));
      previous = distance;
    }
    // The extremes between two samples differ from the sampled ones by less than a sample step.
    r.min = std::max(0.0, r.min - step - 1e-9);
    r.max += step + 1e-9;
    r.shoulder = shoulder;
    r.wrist_in_tool = in_tool;
    r.valid = true;
    return r;
  }
};

/// A rotation uniform over SO(3) (Shoemake's subgroup algorithm).
Eigen::Matrix3d uniformRotation(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double u1 = u(rng), u2 = u(rng), u3 = u(rng);
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  const Eigen::Quaterniond q(b * std::cos(2 * M_PI * u3), a * std::sin(2 * M_PI * u2), a * std::cos(2 * M_PI * u2),
                             b * std::sin(2 * M_PI * u3));
  return q.toRotationMatrix();
}

/// The cache file's header: magic, format version and a byte-order mark.
constexpr char kMagic[8] = {'B', 'S', 'W', 'S', 'M', 'A', 'P', '\0'};
constexpr std::uint32_t kFormatVersion = 1;
constexpr std::uint32_t kByteOrder = 0x01020304u;

/// FNV-1a over the bytes of values, for WorkspaceMap::key.
class Fingerprint {
 public:
  template <typename T>
  Fingerprint& add(const T& value) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    for (const unsigned char b : bytes) hash_ = (hash_ ^ b) * 0x100000001b3ull;
    return *this;
  }
  Fingerprint& add(const Eigen::MatrixXd& m) {
    for (Eigen::Index i = 0; i < m.size(); ++i) add(m.data()[i]);
    return *this;
  }
  std::uint64_t value() const { return hash_; }

 private:
  std::uint64_t hash_ = 0xcbf29ce484222325ull;
};

/// Raw values to and from the cache file (this host's representation; the header's byte-order mark guards it).
template <typename T>
void put(std::ofstream& out, const T& value) {
  out.write(reinterpret_cast<const char*>(&value), sizeof(T));
}
template <typename T>
bool get(std::ifstream& in, T& value) {
  return static_cast<bool>(in.read(reinterpret_cast<char*>(&value), sizeof(T)));
}
void put(std::ofstream& out, const Eigen::Vector3d& v) {
  for (int i = 0; i < 3; ++i) put(out, v[i]);
}
bool get(std::ifstream& in, Eigen::Vector3d& v) {
  return get(in, v[0]) && get(in, v[1]) && get(in, v[2]);
}

/// The fields of a voxel in the cache file, in file order: `field` is called on each until it returns false.
template <typename Voxel, typename Field>
bool voxelFields(Voxel& v, Field&& field) {
  return field(v.centre) && field(v.solved) && field(v.pruned) && field(v.solution_ratio) && field(v.manipulability) &&
         field(v.condition) && field(v.forearm.axis) && field(v.forearm.angle) && field(v.tool.axis) &&
         field(v.tool.angle);
}

}  // namespace

void WorkspaceMapSettings::validate() const {
  if (!(resolution > 0.0) || !std::isfinite(resolution)) throw std::invalid_argument("workspace map: resolution > 0");
  if (orientations < 1) throw std::invalid_argument("workspace map: orientations >= 1");
  if (threads < 0) throw std::invalid_argument("workspace map: threads >= 0 (0: one per core)");
  if (ik_attempts < 1) throw std::invalid_argument("workspace map: ik_attempts >= 1");
  if (forearm_joint < -1) throw std::invalid_argument("workspace map: forearm_joint >= 0 (or -1: the default)");
}

bool WorkspaceMap::mayReach(const Eigen::Isometry3d& tool) const noexcept {
  if (!spherical_) return true;
  const double d = (tool * wrist_in_tool_ - shoulder_).norm();
  return d >= wrist_min_ && d <= wrist_max_;
}

std::size_t WorkspaceMap::reachable() const noexcept {
  return static_cast<std::size_t>(
      std::count_if(voxels_.begin(), voxels_.end(), [](const WorkspaceVoxel& v) { return v.solved > 0; }));
}

WorkspaceMap WorkspaceMap::build(const ChainModel& model, const WorkspaceMapSettings& settings,
                                 const std::function<void(std::size_t, std::size_t)>& progress) {
  settings.validate();
  const int n = model.nq();
  if (n < 3) throw std::invalid_argument("workspace map: the chain needs at least 3 joints");
  const int forearm = settings.forearm_joint >= 0 ? settings.forearm_joint : (n == 7 ? 4 : n - 3);
  if (forearm < 1 || forearm + 1 >= n) throw std::invalid_argument("workspace map: forearm_joint out of the chain");
  WorkspaceMap map;
  map.settings_ = settings;
  const WristReach reach = WristReach::of(model, forearm);
  map.spherical_ = reach.valid;
  map.shoulder_ = reach.shoulder;
  map.wrist_in_tool_ = reach.wrist_in_tool;
  map.wrist_min_ = reach.min;
  map.wrist_max_ = reach.max;

  // The grid: a cube around the shoulder centre (or the base) that holds the reach bound.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  if (reach.valid) {
    centre = reach.shoulder;
    map.reach_ = reach.max + reach.wrist_in_tool.norm();
  } else {
    ChainData data(model);
    std::mt19937 rng(settings.seed);
    for (int k = 0; k < 20000; ++k) {
      forward(model, data, kinematics::randomWithinLimits(model, rng));
      map.reach_ = std::max(map.reach_, data.tipPose().translation().norm());
    }
    map.reach_ *= 1.05;
  }
  const double h = settings.resolution;
  const int cells = static_cast<int>(std::ceil(2.0 * map.reach_ / h));
  const Eigen::Vector3d corner = centre - Eigen::Vector3d::Constant(0.5 * cells * h);
  const double keep = map.reach_ + 0.5 * std::sqrt(3.0) * h;
  for (int z = 0; z < cells; ++z) {
    for (int y = 0; y < cells; ++y) {
      for (int x = 0; x < cells; ++x) {
        WorkspaceVoxel v;
        v.centre = corner + h * Eigen::Vector3d(x + 0.5, y + 0.5, z + 0.5);
        if ((v.centre - centre).norm() <= keep) map.voxels_.push_back(v);
      }
    }
  }

  const double wrist_limit =
      std::max(std::abs(model.lowerLimits()[forearm + 1]), std::abs(model.upperLimits()[forearm + 1]));
  // Per thread: a solver, kinematic scratch and the axes found; voxels are handed out one at a time, each with its
  // own generator, so the map does not depend on the number of threads.
  struct Worker {
    kinematics::GlobalIkSolver solver;
    ChainData data;
    Eigen::VectorXd q;
    std::vector<Eigen::Vector3d> axes;
  };
  kinematics::GlobalIkParameters ik;
  ik.max_attempts = settings.ik_attempts;
  ik.timeout = kNoTimeBudget;
  ik.seed = settings.seed;
  const int threads = parallel::threadCount(settings.threads);
  std::vector<std::unique_ptr<Worker>> workers;
  for (int t = 0; t < threads; ++t) {
    workers.push_back(std::make_unique<Worker>(
        Worker{kinematics::GlobalIkSolver(model, ik), ChainData(model), Eigen::VectorXd(n), {}}));
  }
  const Eigen::VectorXd start = midLimits(model);
  std::atomic<std::size_t> done{0};
  auto last_progress = std::chrono::steady_clock::now();
  parallel::parallelFor(map.voxels_.size(), threads, [&](int worker, std::size_t i) {
    kinematics::GlobalIkSolver& solver = workers[static_cast<std::size_t>(worker)]->solver;
    ChainData& data = workers[static_cast<std::size_t>(worker)]->data;
    Eigen::VectorXd& q = workers[static_cast<std::size_t>(worker)]->q;
    std::vector<Eigen::Vector3d>& axes = workers[static_cast<std::size_t>(worker)]->axes;
    WorkspaceVoxel& v = map.voxels_[i];
    std::seed_seq sequence{settings.seed, static_cast<std::uint32_t>(i), 0x3a9u};
    std::mt19937 rng(sequence);
    Eigen::VectorXd seed = start;
    axes.clear();
    for (int m = 0; m < settings.orientations; ++m) {
      Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
      target.linear() = uniformRotation(rng);
      target.translation() = v.centre;
      if (settings.wrist_test && !map.mayReach(target)) {
        ++v.pruned;
        continue;
      }
      const kinematics::GlobalIkResult r = solver.solve(target, seed, q);
      if (r.status != kinematics::IkStatus::Converged) continue;
      seed = q;
      ++v.solved;
      if (kinematics::computeJacobian(model, data, q) != kinematics::KinematicsStatus::Success) continue;
      v.manipulability += kinematics::manipulability(data);
      v.condition += kinematics::conditionNumber(data);
      Eigen::Vector3d axis = axisDirection(data, forearm);
      const Eigen::Vector3d along = axisOrigin(data, forearm + 1) - axisOrigin(data, forearm - 1);
      if (axis.dot(along) < 0.0) axis = -axis;
      axes.push_back(axis);
    }
    v.solution_ratio = static_cast<double>(v.solved) / settings.orientations;
    if (v.solved > 0) {
      v.manipulability /= v.solved;
      v.condition /= v.solved;
      v.forearm = minimalBoundingCone(axes, settings.seed);
      v.tool = v.forearm;
      v.tool.angle = std::min(M_PI, v.forearm.angle + wrist_limit);
    }
    ++done;
    if (worker == 0 && progress && std::chrono::steady_clock::now() - last_progress > std::chrono::milliseconds(500)) {
      last_progress = std::chrono::steady_clock::now();
      progress(done, map.voxels_.size());
    }
  });
  if (progress) progress(done, map.voxels_.size());
  return map;
}

std::uint64_t WorkspaceMap::key(const ChainModel& model, const WorkspaceMapSettings& settings) {
  Fingerprint f;
  f.add(kFormatVersion).add(model.nq());
  for (const kinematics::ChainJoint& joint : model.joints()) {
    f.add(static_cast<int>(joint.type)).add(Eigen::MatrixXd(joint.origin.matrix())).add(Eigen::MatrixXd(joint.axis));
    f.add(joint.lower).add(joint.upper);
  }
  f.add(Eigen::MatrixXd(model.tipInLastFrame().matrix()));
  f.add(settings.resolution).add(settings.orientations).add(settings.seed).add(settings.ik_attempts);
  f.add(settings.forearm_joint).add(settings.wrist_test);
  return f.value();
}

template <typename Map, typename Field>
bool WorkspaceMap::headerFields(Map& map, Field&& field) {
  return field(map.settings_.resolution) && field(map.settings_.orientations) && field(map.settings_.seed) &&
         field(map.settings_.ik_attempts) && field(map.settings_.forearm_joint) && field(map.settings_.wrist_test) &&
         field(map.spherical_) && field(map.reach_) && field(map.shoulder_) && field(map.wrist_in_tool_) &&
         field(map.wrist_min_) && field(map.wrist_max_);
}

void WorkspaceMap::save(const std::string& path, std::uint64_t key) const {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("workspace map: cannot write " + partial);
    out.write(kMagic, sizeof kMagic);
    put(out, kFormatVersion);
    put(out, kByteOrder);
    put(out, key);
    const auto write = [&](const auto& value) {
      put(out, value);
      return true;
    };
    headerFields(*this, write);
    put(out, static_cast<std::uint64_t>(voxels_.size()));
    for (const WorkspaceVoxel& v : voxels_) voxelFields(v, write);
    if (!out.flush()) throw std::runtime_error("workspace map: cannot write " + partial);
  }
  // Complete or absent: a reader never sees half a file.
  std::filesystem::rename(partial, path);
}

std::optional<WorkspaceMap> WorkspaceMap::load(const std::string& path, std::uint64_t key) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  char magic[sizeof kMagic];
  std::uint32_t version = 0, order = 0;
  std::uint64_t stored = 0, count = 0;
  if (!in.read(magic, sizeof magic) || std::memcmp(magic, kMagic, sizeof kMagic) != 0 || !get(in, version) ||
      version != kFormatVersion || !get(in, order) || order != kByteOrder || !get(in, stored) || stored != key) {
    return std::nullopt;
  }
  WorkspaceMap map;
  const auto read = [&](auto& value) { return get(in, value); };
  if (!headerFields(map, read) || !get(in, count) || count > (std::uint64_t{1} << 32)) return std::nullopt;
  map.voxels_.resize(static_cast<std::size_t>(count));
  for (WorkspaceVoxel& v : map.voxels_) {
    if (!voxelFields(v, read)) return std::nullopt;
  }
  char extra = 0;
  if (in.read(&extra, 1)) return std::nullopt;  // trailing bytes: not a file this code wrote
  return map;
}

std::string WorkspaceMap::defaultCacheDirectory() {
  const char* home = std::getenv("HOME");
  return home != nullptr ? std::string(home) + "/.cache/bimanual_skills/workspace" : std::string();
}

std::string WorkspaceMap::cachePath(const std::string& directory, const ChainModel& model,
                                    const WorkspaceMapSettings& settings) {
  char name[40];
  std::snprintf(name, sizeof name, "workspace_%016llx.map", static_cast<unsigned long long>(key(model, settings)));
  return (std::filesystem::path(directory) / name).string();
}

WorkspaceMap WorkspaceMap::cached(const ChainModel& model, const WorkspaceMapSettings& settings,
                                  const std::string& directory,
                                  const std::function<void(std::size_t, std::size_t)>& progress, bool* from_cache) {
  const std::uint64_t k = key(model, settings);
  if (!directory.empty()) {
    if (std::optional<WorkspaceMap> map = load(cachePath(directory, model, settings), k)) {
      map->settings_.threads = settings.threads;
      if (from_cache != nullptr) *from_cache = true;
      return std::move(*map);
    }
  }
  WorkspaceMap map = build(model, settings, progress);
  if (!directory.empty()) {
    std::filesystem::create_directories(directory);
    map.save(cachePath(directory, model, settings), k);
  }
  if (from_cache != nullptr) *from_cache = false;
  return map;
}

}  // namespace bimanual_skills::workspace
