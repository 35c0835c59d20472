#include "preprocess/validate.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace strata {

namespace {

bool isFinite(const glm::vec3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

glm::dvec3 toDouble(const glm::vec3& p) { return glm::dvec3(p); }

}  // namespace

TriangleFault classifyTriangle(const std::vector<glm::vec3>& positions, uint32_t a, uint32_t b,
                               uint32_t c) {
  const size_t n = positions.size();
  if (a >= n || b >= n || c >= n) return TriangleFault::kOutOfRange;
  const glm::vec3& pa = positions[a];
  const glm::vec3& pb = positions[b];
  const glm::vec3& pc = positions[c];
  if (!isFinite(pa) || !isFinite(pb) || !isFinite(pc)) return TriangleFault::kNonFinite;
  if (a == b || b == c || a == c) return TriangleFault::kDegenerate;

  // Double precision: float products of large coordinates could overflow or lose the small
  // cross product of a thin but valid triangle.
  const glm::dvec3 ab = toDouble(pb) - toDouble(pa);
  const glm::dvec3 ac = toDouble(pc) - toDouble(pa);
  const glm::dvec3 bc = toDouble(pc) - toDouble(pb);
  const double doubled_area = glm::length(glm::cross(ab, ac));
  const double longest_sq = std::max({glm::dot(ab, ab), glm::dot(ac, ac), glm::dot(bc, bc)});
  if (doubled_area == 0.0 || doubled_area <= kDegenerateRelativeArea * longest_sq)
    return TriangleFault::kDegenerate;
  return TriangleFault::kNone;
}

void validateMesh(Mesh& mesh, LoadReport& report) {
  std::vector<uint32_t>& idx = mesh.indices;
  const size_t whole = idx.size() / 3 * 3;
  if (whole != idx.size()) {
    // A partial triangle can only come from a loader bug or a truncated index list; it refers
    // to corners that do not exist.
    ++report.dropped_out_of_range;
    idx.resize(whole);
  }
  size_t kept = 0;
  for (size_t t = 0; t < whole; t += 3) {
    switch (classifyTriangle(mesh.positions, idx[t], idx[t + 1], idx[t + 2])) {
      case TriangleFault::kOutOfRange:
        ++report.dropped_out_of_range;
        continue;
      case TriangleFault::kNonFinite:
        ++report.dropped_nonfinite;
        continue;
      case TriangleFault::kDegenerate:
        ++report.dropped_degenerate;
        continue;
      case TriangleFault::kNone:
        break;
    }
    idx[kept] = idx[t];
    idx[kept + 1] = idx[t + 1];
    idx[kept + 2] = idx[t + 2];
    kept += 3;
  }
  idx.resize(kept);
  report.triangles_loaded += kept / 3;
}

void validateScene(Scene& scene) {
  LoadReport& report = scene.report;
  for (Mesh& mesh : scene.meshes) validateMesh(mesh, report);

  // Compact away empty meshes and remap the instances that remain.
  std::vector<uint32_t> new_index(scene.meshes.size(), UINT32_MAX);
  std::vector<Mesh> kept_meshes;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    if (scene.meshes[m].indices.empty()) continue;
    new_index[m] = static_cast<uint32_t>(kept_meshes.size());
    kept_meshes.push_back(std::move(scene.meshes[m]));
  }
  scene.meshes = std::move(kept_meshes);
  std::vector<Instance> kept_instances;
  for (Instance& inst : scene.instances) {
    if (inst.mesh >= new_index.size() || new_index[inst.mesh] == UINT32_MAX) continue;
    inst.mesh = new_index[inst.mesh];
    kept_instances.push_back(std::move(inst));
  }
  scene.instances = std::move(kept_instances);

  if (scene.instances.empty()) {
    const uint64_t dropped =
        report.dropped_nonfinite + report.dropped_out_of_range + report.dropped_degenerate;
    std::string msg = scene.source + ": no triangles";
    if (dropped > 0) {
      msg += " (dropped " + std::to_string(report.dropped_out_of_range) +
             " with an index out of "
             "range, " +
             std::to_string(report.dropped_nonfinite) + " with a non-finite vertex, " +
             std::to_string(report.dropped_degenerate) + " of zero area)";
    } else if (!report.warnings.empty()) {
      // Nothing was dropped, so the reason is what the loader skipped (points, lines, ...).
      msg += " (" + report.warnings.front();
      if (report.warnings.size() > 1)
        msg += "; " + std::to_string(report.warnings.size() - 1) + " more warnings";
      msg += ")";
    } else {
      msg += " in the file";
    }
    throw Error(msg);
  }
}

}  // namespace strata
