// The public API's threading contract (include/strata/strata.h): calls on one Renderer or Picker
// from several threads are serialised, setGeometry during a render neither waits for it nor
// disturbs it (the frame keeps its geometry), and separate Renderers on one Device render at
// once, each frame equal to the one rendered alone.
#include <algorithm>
#include <atomic>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "strata/strata.h"

namespace strata {
namespace {

View viewAt(float azimuth) {
  View v;
  v.azimuth_deg = azimuth;
  v.width = v.height = 96;
  return v;
}

TEST(PublicApiThreads, OneRendererSharedByThreads) {
  Device device = Device::open();
  Renderer renderer(device, "cells");
  renderer.setGeometry(Geometry::load("builtin:spheres:16"));
  std::vector<Image> expected;
  for (int t = 0; t < 4; ++t) expected.push_back(renderer.render(viewAt(30.0f + t)).image);
  std::atomic<int> differing{0}, failed{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      try {
        for (int frame = 0; frame < 3; ++frame)
          if (renderer.render(viewAt(30.0f + t)).image.rgba != expected[t].rgba) ++differing;
      } catch (const Error&) {
        ++failed;
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(differing.load(), 0);
  EXPECT_EQ(failed.load(), 0);
}

TEST(PublicApiThreads, GeometryReplacedDuringRenders) {
  Device device = Device::open();
  Renderer renderer(device, "ppll");
  const std::vector<std::string> scenes = {"builtin:spheres:16", "builtin:demo"};
  std::vector<Image> expected;
  for (const std::string& s : scenes) {
    renderer.setGeometry(Geometry::load(s));  // the renderer holds the only reference
    expected.push_back(renderer.render(viewAt(30.0f)).image);
  }
  std::atomic<bool> stop{false};
  std::atomic<int> strange{0}, frames{0};
  std::thread worker([&] {
    while (!stop) {
      const Image image = renderer.render(viewAt(30.0f)).image;
      if (image.rgba != expected[0].rgba && image.rgba != expected[1].rgba) ++strange;
      ++frames;
    }
  });
  for (int i = 0; i < 12; ++i) renderer.setGeometry(Geometry::load(scenes[i % 2]));
  stop = true;
  worker.join();
  EXPECT_EQ(strange.load(), 0) << "of " << frames.load() << " frames";
}

TEST(PublicApiThreads, SeparateRenderersOnOneDevice) {
  Device device = Device::open();
  const Geometry geometry = Geometry::load("builtin:demo");
  const std::vector<std::string> methods = {"ppll", "cells", "octree", "abuffer", "embree"};
  std::vector<Image> expected;
  for (const std::string& m : methods) {
    Renderer r(device, m);
    r.setGeometry(geometry);
    expected.push_back(r.render(viewAt(40.0f)).image);
  }
  std::vector<int> differing(methods.size(), 0);
  std::vector<std::string> errors(methods.size());
  std::vector<std::thread> threads;
  for (size_t i = 0; i < methods.size(); ++i)
    threads.emplace_back([&, i] {
      try {
        Renderer r(device, methods[i]);
        r.setGeometry(geometry);
        for (int frame = 0; frame < 4; ++frame)
          if (r.render(viewAt(40.0f)).image.rgba != expected[i].rgba) ++differing[i];
      } catch (const Error& e) {
        errors[i] = e.what();
      }
    });
  for (std::thread& t : threads) t.join();
  for (size_t i = 0; i < methods.size(); ++i) {
    EXPECT_EQ(differing[i], 0) << methods[i];
    EXPECT_EQ(errors[i], "") << methods[i];
  }
}

TEST(PublicApiThreads, OnePickerSharedByThreads) {
  Device device = Device::open();
  Picker picker(device);
  picker.setGeometry(Geometry::load("builtin:demo"));
  const std::vector<std::pair<int, int>> pixels = {{48, 48}, {10, 10}, {60, 40}};
  const std::vector<PickHit> expected = picker.pick(viewAt(30.0f), pixels);
  std::atomic<int> differing{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int round = 0; round < 5; ++round) {
        const std::vector<PickHit> hits = picker.pick(viewAt(30.0f), pixels);
        if (hits.size() != expected.size()) ++differing;
        for (size_t p = 0; p < std::min(hits.size(), expected.size()); ++p)
          if (hits[p].hit != expected[p].hit || hits[p].triangle != expected[p].triangle ||
              hits[p].depth != expected[p].depth)
            ++differing;
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(differing.load(), 0);
}

TEST(PublicApiThreads, AViewThatCannotBeFramedIsAnError) {
  Device device = Device::open();
  Renderer renderer(device, "embree");
  renderer.setGeometry(Geometry::load("builtin:demo"));
  View far = viewAt(30.0f);
  far.distance = 1e30f;
  EXPECT_THROW(renderer.render(far), Error);
  View bad = viewAt(30.0f);
  bad.look_at = true;
  bad.eye[0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(renderer.render(bad), Error);
}

}  // namespace
}  // namespace strata
