// `strata render --distributed` under mpirun: sort-last rendering of an octree scene split into
// one convex box per process (preprocess/octree_partition.h), each process rendering only its
// box's leaves, read from the octree scene's file, and the shares composited in visibility
// order by MPI's own collectives (docs/distributed.md).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "engine/renderer.h"

namespace strata {

struct DistributedJob {
  std::string scene;  // a mesh file, builtin:NAME or an octree scene (FILE.octree)
  std::string output, stats;
  std::string cache;  // octree cache folder (empty: the user's): where a mesh's octree scene goes
  float alpha = -1.0f;
  bool sigma_given = false;  // else sigma is 1 / the scene's bounding-sphere radius
  FrameSettings settings;    // all but the camera and the share
  std::function<Camera(const Scene&)> camera;  // the view of the loaded scene
  std::string view_options;  // the options camera() is made from, as given: every rank's agree
  DeviceOptions device;
  // How long a rank may go without answering while another waits for it in a collective (a
  // busy rank answers): then every rank exits, naming it.
  double rank_timeout_s = 60.0;
  int fail_rank = -1;  // testing: this rank throws during its render
  int fail_rank_late = -1;  // testing: this rank throws before the composite, on its own
};

// Whether this strata was built with MPI.
bool distributedAvailable();
// False in the processes of an MPI job but the first (from the launcher's environment, so it
// holds before MPI is initialized).
bool firstMpiProcess();

// Runs one process's part and returns its exit status; rank 0 writes the image and the
// statistics and prints the one-line error when any rank failed.
int runDistributedRender(const DistributedJob& job);

// `strata bench --distributed`: each scene rendered by `mpirun -np P` for every P, side by side,
// into out_dir: results.json (every rank's figures), results.md (the scaling table) and the
// images; each image is compared with the one-process image.
struct DistributedBench {
  std::vector<std::string> scenes{"builtin:hairball", "builtin:city", "builtin:shells"};
  std::vector<int> processes{1, 2, 3, 4};
  int width = 640, height = 480, frames = 3;
  std::string out_dir = "bench-out";
  std::string device;
};
int runDistributedBench(const DistributedBench& bench);

}  // namespace strata
