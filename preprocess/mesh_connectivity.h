// Half-edge connectivity of a triangle mesh (preprocess/mesh_connectivity.cpp): the triangles are
// added to an OpenMesh half-edge mesh over welded vertices, and every edge lists the face sides
// (slots) on it. Real inputs are triangle soups with duplicate faces, flipped windings, edges with
// three or more faces and zero-area triangles; OpenMesh refuses a face that would make its mesh
// non-manifold (a complex edge or vertex). Such a face is not lost: it is reported as non-manifold
// and joins the edges it shares by their vertex pair, so every edge holds all the faces that have
// both its vertices as corners, whatever their winding (the rule the convex decomposition grows
// cells by). OpenMesh stays inside the .cpp: this header includes no OpenMesh.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "preprocess/mesh_view.h"

namespace strata {

struct ConnectivityOptions {
  // Vertices with bitwise-equal finite positions (+0 and -0 equal) are one vertex, as in the
  // convex decomposition (soups, meshes split at normal or texture seams); off: the index
  // buffer's vertices as given.
  bool weld_positions = true;
  // Optional, one entry per vertex: the caller's own welding (vertex -> its representative, a
  // vertex mapping to itself), used instead of weld_positions' (the decomposition passes the
  // map it has already computed).
  const uint32_t* vertex_map = nullptr;
  // Optional, one byte per triangle: non-zero leaves the triangle out (no edges, no neighbours),
  // e.g. the decomposition's zero-area and non-finite triangles.
  const uint8_t* exclude = nullptr;
};

enum class FaceKind : uint8_t {
  Manifold,     // a face of the half-edge mesh
  NonManifold,  // refused by the half-edge mesh (complex edge or vertex: a third face on an edge,
                // a duplicate, a winding flipped against its neighbours, two fans on one vertex);
                // its edges found by their vertex pairs
  Degenerate,   // two corners are one (welded) vertex: no edges
  Excluded,     // left out through ConnectivityOptions::exclude: no edges
};
const char* faceKindName(FaceKind kind);

// A contiguous run of slots (slot = 3 * triangle + k: the edge from corner k to corner (k+1)%3).
struct SlotRange {
  const uint32_t* first = nullptr;
  const uint32_t* last = nullptr;
  const uint32_t* begin() const { return first; }
  const uint32_t* end() const { return last; }
  size_t size() const { return size_t(last - first); }
};

class MeshConnectivity {
 public:
  static constexpr uint32_t kNone = UINT32_MAX;

  // Throws Error for an index past the vertex count or a mesh too large for 32-bit slots.
  explicit MeshConnectivity(const MeshView& mesh, const ConnectivityOptions& options = {});

  size_t triangleCount() const { return kind_.size(); }
  // Corner k of triangle t as a welded vertex (the first vertex with its position).
  uint32_t vertex(uint32_t t, int k) const { return corner_[3 * size_t(t) + k]; }
  FaceKind faceKind(uint32_t t) const { return FaceKind(kind_[t]); }

  // Edges: every distinct vertex pair that is an edge of a Manifold or NonManifold triangle.
  uint32_t edgeCount() const { return uint32_t(edge_begin_.size() - 1); }
  // The edge of slot 3 * t + k; kNone for Degenerate and Excluded triangles.
  uint32_t edgeOfSlot(uint32_t slot) const { return slot_edge_[slot]; }
  uint32_t edgeOf(uint32_t t, int k) const { return slot_edge_[3 * size_t(t) + k]; }
  // The slots on edge e, ascending (so, by triangle).
  SlotRange edgeSlots(uint32_t e) const {
    return {edge_slots_.data() + edge_begin_[e], edge_slots_.data() + edge_begin_[e + 1]};
  }
  uint32_t edgeFaceCount(uint32_t e) const { return edge_begin_[e + 1] - edge_begin_[e]; }
  bool isBoundaryEdge(uint32_t e) const { return edgeFaceCount(e) == 1; }
  bool isNonManifoldEdge(uint32_t e) const { return edgeFaceCount(e) >= 3; }
  // Exactly two faces, running the edge the same way (a flipped winding, or a duplicate face);
  // OpenMesh can hold only one of them.
  bool isInconsistentEdge(uint32_t e) const;

  // The triangles across edge k of triangle t (every other face on that edge), ascending.
  std::vector<uint32_t> neighbours(uint32_t t, int k) const;
  // The triangles sharing any edge with t, ascending and distinct.
  std::vector<uint32_t> faceNeighbours(uint32_t t) const;

  std::vector<uint32_t> boundaryEdges() const;
  std::vector<uint32_t> nonManifoldEdges() const;  // three or more faces
  std::vector<uint32_t> nonManifoldFaces() const;  // FaceKind::NonManifold, ascending

  struct Counts {
    size_t vertices = 0;        // distinct welded vertices used by edges
    size_t halfedge_faces = 0;  // FaceKind::Manifold
    size_t nonmanifold_faces = 0, degenerate_faces = 0, excluded_faces = 0;
    size_t edges = 0, boundary_edges = 0, nonmanifold_edges = 0, inconsistent_edges = 0;
  };
  const Counts& counts() const { return counts_; }

 private:
  std::vector<uint32_t> corner_;      // 3 per triangle
  std::vector<uint8_t> kind_;         // FaceKind per triangle
  std::vector<uint32_t> slot_edge_;   // 3 per triangle
  std::vector<uint32_t> edge_begin_;  // edgeCount() + 1 offsets into edge_slots_
  std::vector<uint32_t> edge_slots_;
  Counts counts_;
};

}  // namespace strata
