// `strata render --distributed` under mpirun: sort-last rendering of an octree scene split into
// one convex box per process (preprocess/octree_partition.h), each process rendering only its
// box's leaves, read from the octree scene's file, and the shares composited in visibility
// order by MPI's own collectives (docs/distributed.md).
#pragma once

#include <functional>
#include <string>

#include "engine/renderer.h"

namespace strata {

struct DistributedJob {
  std::string scene;  // a mesh file, builtin:NAME or an octree scene (FILE.octree)
  std::string output, stats;
  std::string cache;  // octree cache folder (empty: the user's): where a mesh's octree scene goes
  float alpha = -1.0f;
  FrameSettings settings;                      // all but the camera and the share
  std::function<Camera(const Scene&)> camera;  // the view of the loaded scene
  DeviceOptions device;
  int fail_rank = -1;  // testing: this rank throws during its render
};

// Whether this strata was built with MPI.
bool distributedAvailable();
// False in the processes of an MPI job but the first (from the launcher's environment, so it
// holds before MPI is initialized).
bool firstMpiProcess();

// Runs one process's part and returns its exit status; rank 0 writes the image and the
// statistics and prints the one-line error when any rank failed.
int runDistributedRender(const DistributedJob& job);

}  // namespace strata
