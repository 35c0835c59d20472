// Half-edge connectivity through OpenMesh (preprocess/mesh_connectivity.h).
//
// The triangles go, in index order, into an OpenMesh::PolyConnectivity over the welded vertices
// (connectivity only: no points are stored). A face add_face refuses (complex edge: the edge
// already has a face on that side, as for a third face on an edge, a duplicate or a flipped
// winding; complex vertex or failed patch re-linking: a fan would be split) is retried once the
// others are in, and if still refused becomes FaceKind::NonManifold. Each OpenMesh edge is one of
// our edges, holding the faces of its two half-edges; a refused face joins the OpenMesh edge of
// each of its vertex pairs (find_halfedge), or, where OpenMesh has none, an edge shared only with
// other refused faces (a hash on the pair). So an edge holds every face with both its vertices as
// corners, which is exactly the grouping by vertex pair, and manifold regions are the half-edge
// mesh's own.
#include "preprocess/mesh_connectivity.h"

#include <algorithm>
#include <string>
#include <unordered_map>

#include <OpenMesh/Core/Mesh/PolyConnectivity.hh>
#include "preprocess/openmesh_quiet.h"

#include "preprocess/cell_convexity.h"
#include "preprocess/core/enum_table.h"
#include "strata/error.h"

namespace strata {

const char* faceKindName(FaceKind kind) {
  static constexpr const char* kNames[] = {"manifold", "non-manifold", "degenerate", "excluded"};
  return enumLookup(kind, kNames, "unknown");
}

MeshConnectivity::MeshConnectivity(const MeshView& mesh, const ConnectivityOptions& options) {
  const size_t T = mesh.triangle_count, V = mesh.vertex_count;
  if (T >= size_t(UINT32_MAX) / 3 || V >= size_t(UINT32_MAX))
    throw Error("MeshConnectivity: mesh too large (" + std::to_string(T) + " triangles, " +
                std::to_string(V) + " vertices)");
  if (T > 0 && !mesh.indices) throw Error("MeshConnectivity: mesh has triangles but no indices");
  for (size_t i = 0; i < 3 * T; ++i)
    if (mesh.indices[i] >= V)
      throw Error("MeshConnectivity: triangle " + std::to_string(i / 3) + " has vertex index " +
                  std::to_string(mesh.indices[i]) + " past the vertex count " + std::to_string(V));

  std::vector<uint32_t> own_weld;
  const uint32_t* weld = options.vertex_map;
  if (weld) {
    for (size_t v = 0; v < V; ++v)
      if (weld[v] >= V || weld[weld[v]] != weld[v])
        throw Error("MeshConnectivity: vertex_map sends vertex " + std::to_string(v) +
                    " to a vertex that is not its own representative");
  } else if (options.weld_positions && V > 0) {
    if (!mesh.positions)
      throw Error("MeshConnectivity: welding needs positions, the mesh has none");
    cells_detail::weldVertices(mesh, &own_weld);
    weld = own_weld.data();
  }
  corner_.resize(3 * T);
  for (size_t i = 0; i < 3 * T; ++i) corner_[i] = weld ? weld[mesh.indices[i]] : mesh.indices[i];

  // Faces: kinds, and OpenMesh vertices for the corners of the candidates.
  kind_.assign(T, uint8_t(FaceKind::Manifold));
  std::vector<uint32_t> om_vertex(V, kNone);  // welded vertex -> OpenMesh vertex index
  std::vector<uint32_t> om_welded;            // OpenMesh vertex index -> welded vertex
  std::vector<uint32_t> pending;
  pending.reserve(T);
  for (size_t t = 0; t < T; ++t) {
    const uint32_t* c = &corner_[3 * t];
    if (options.exclude && options.exclude[t]) {
      kind_[t] = uint8_t(FaceKind::Excluded);
    } else if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
      kind_[t] = uint8_t(FaceKind::Degenerate);
    } else {
      pending.push_back(uint32_t(t));
      for (int k = 0; k < 3; ++k)
        if (om_vertex[c[k]] == kNone) {
          om_vertex[c[k]] = uint32_t(om_welded.size());
          om_welded.push_back(c[k]);
        }
    }
  }

  OpenMesh::PolyConnectivity om;
  om.reserve(om_welded.size(), pending.size() * 3 / 2 + 3, pending.size());
  for (size_t i = 0; i < om_welded.size(); ++i) om.new_vertex();
  std::vector<uint32_t> face_triangle;  // OpenMesh face index -> triangle
  face_triangle.reserve(pending.size());
  auto vh = [&](uint32_t welded) { return OpenMesh::VertexHandle(int(om_vertex[welded])); };
  {
    const QuietOmerr quiet;
    // Refused faces are retried after the others: a refusal for a split fan can depend on the
    // order faces arrive in. A refusal for a complex edge stands (its edge only gains faces).
    for (int pass = 0; pass < 3 && !pending.empty(); ++pass) {
      std::vector<uint32_t> refused;
      for (uint32_t t : pending) {
        const uint32_t* c = &corner_[3 * size_t(t)];
        const OpenMesh::FaceHandle fh = om.add_face(vh(c[0]), vh(c[1]), vh(c[2]));
        if (fh.is_valid()) {
          face_triangle.push_back(t);
        } else {
          refused.push_back(t);
        }
      }
      const bool progress = refused.size() < pending.size();
      pending.swap(refused);
      if (!progress) break;
    }
  }
  for (uint32_t t : pending) kind_[t] = uint8_t(FaceKind::NonManifold);

  // Slot -> edge: OpenMesh edges first, from the half-edges of each face.
  slot_edge_.assign(3 * T, kNone);
  for (size_t f = 0; f < face_triangle.size(); ++f) {
    const uint32_t t = face_triangle[f];
    OpenMesh::HalfedgeHandle h = om.halfedge_handle(OpenMesh::FaceHandle(int(f)));
    for (int i = 0; i < 3; ++i, h = om.next_halfedge_handle(h)) {
      const uint32_t from = om_welded[size_t(om.from_vertex_handle(h).idx())];
      const int k = corner_[3 * size_t(t)] == from ? 0 : corner_[3 * size_t(t) + 1] == from ? 1 : 2;
      slot_edge_[3 * size_t(t) + k] = uint32_t(om.edge_handle(h).idx());
    }
  }
  uint32_t edges = uint32_t(om.n_edges());
  // Refused faces: the OpenMesh edge of the vertex pair, else an edge among refused faces.
  std::unordered_map<uint64_t, uint32_t> extra;
  for (uint32_t t : pending) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = corner_[3 * size_t(t) + k], b = corner_[3 * size_t(t) + (k + 1) % 3];
      const OpenMesh::HalfedgeHandle h = om.find_halfedge(vh(a), vh(b));
      uint32_t e;
      if (h.is_valid()) {
        e = uint32_t(om.edge_handle(h).idx());
      } else {
        const uint64_t key = (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
        e = extra.emplace(key, edges).first->second;
        if (e == edges) ++edges;
      }
      slot_edge_[3 * size_t(t) + k] = e;
    }
  }

  // Edge -> slots by a counting sort over ascending slots, so each edge's slots are ascending.
  edge_begin_.assign(size_t(edges) + 1, 0);
  for (uint32_t e : slot_edge_)
    if (e != kNone) ++edge_begin_[size_t(e) + 1];
  for (size_t e = 0; e < edges; ++e) edge_begin_[e + 1] += edge_begin_[e];
  edge_slots_.resize(edge_begin_[edges]);
  std::vector<uint32_t> fill(edge_begin_.begin(), edge_begin_.end() - 1);
  for (size_t s = 0; s < slot_edge_.size(); ++s)
    if (slot_edge_[s] != kNone) edge_slots_[fill[slot_edge_[s]]++] = uint32_t(s);

  counts_.vertices = om_welded.size();
  counts_.halfedge_faces = face_triangle.size();
  counts_.nonmanifold_faces = pending.size();
  for (uint8_t k : kind_) {
    counts_.degenerate_faces += k == uint8_t(FaceKind::Degenerate);
    counts_.excluded_faces += k == uint8_t(FaceKind::Excluded);
  }
  counts_.edges = edges;
  for (uint32_t e = 0; e < edges; ++e) {
    counts_.boundary_edges += isBoundaryEdge(e);
    counts_.nonmanifold_edges += isNonManifoldEdge(e);
    counts_.inconsistent_edges += isInconsistentEdge(e);
  }
}

bool MeshConnectivity::isInconsistentEdge(uint32_t e) const {
  if (edgeFaceCount(e) != 2) return false;
  const uint32_t s0 = edge_slots_[edge_begin_[e]], s1 = edge_slots_[edge_begin_[e] + 1];
  return corner_[s0] == corner_[s1];  // both start at the same vertex: same direction
}

std::vector<uint32_t> MeshConnectivity::neighbours(uint32_t t, int k) const {
  std::vector<uint32_t> out;
  const uint32_t e = edgeOf(t, k);
  if (e == kNone) return out;
  for (uint32_t s : edgeSlots(e))
    if (s / 3 != t) out.push_back(s / 3);
  return out;
}

std::vector<uint32_t> MeshConnectivity::faceNeighbours(uint32_t t) const {
  std::vector<uint32_t> out;
  for (int k = 0; k < 3; ++k) {
    const std::vector<uint32_t> n = neighbours(t, k);
    out.insert(out.end(), n.begin(), n.end());
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<uint32_t> MeshConnectivity::boundaryEdges() const {
  std::vector<uint32_t> out;
  for (uint32_t e = 0; e < edgeCount(); ++e)
    if (isBoundaryEdge(e)) out.push_back(e);
  return out;
}

std::vector<uint32_t> MeshConnectivity::nonManifoldEdges() const {
  std::vector<uint32_t> out;
  for (uint32_t e = 0; e < edgeCount(); ++e)
    if (isNonManifoldEdge(e)) out.push_back(e);
  return out;
}

std::vector<uint32_t> MeshConnectivity::nonManifoldFaces() const {
  std::vector<uint32_t> out;
  for (uint32_t t = 0; t < triangleCount(); ++t)
    if (faceKind(t) == FaceKind::NonManifold) out.push_back(t);
  return out;
}

}  // namespace strata
