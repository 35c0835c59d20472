#include "engine/renderer.h"

#include <algorithm>

#include "engine/cl_renderer.h"
#include "engine/embree_reference.h"

namespace strata {

namespace {
struct MethodEntry {
  Method method;
  const char* name;
};
const MethodEntry kMethods[] = {
    {Method::Opaque, "opaque"},
    {Method::Ppll, "ppll"},
    {Method::Abuffer, "abuffer"},
    {Method::Mdts, "mdts"},
    {Method::Mdts32, "mdts32"},
    {Method::Dp, "dp"},
    {Method::Ddp, "ddp"},
    {Method::Bdp, "bdp"},
    {Method::Bdp2, "bdp2"},
    {Method::Cells, "cells"},
    {Method::Embree, "embree"},
};
}  // namespace

Method parseMethod(const std::string& name) {
  for (const MethodEntry& m : kMethods)
    if (name == m.name) return m.method;
  std::string known;
  for (const MethodEntry& m : kMethods) known += std::string(known.empty() ? "" : ", ") + m.name;
  throw Error("unknown method '" + name + "' (known: " + known + ")");
}

std::string methodName(Method method) {
  for (const MethodEntry& m : kMethods)
    if (m.method == method) return m.name;
  return "?";
}

std::vector<std::string> methodNames() {
  std::vector<std::string> out;
  for (const MethodEntry& m : kMethods) out.push_back(m.name);
  return out;
}

std::unique_ptr<Renderer> makeRenderer(Method method, const DeviceOptions& device) {
  if (method == Method::Embree) return makeEmbreeRenderer(EmbreeMode::Transparency);
  return makeClRenderer(method, device);
}

FrameTimes summarizeTimes(std::vector<double> ms) {
  FrameTimes t;
  t.runs = int(ms.size());
  if (ms.empty()) return t;
  std::sort(ms.begin(), ms.end());
  t.min = ms.front();
  t.max = ms.back();
  const size_t n = ms.size();
  t.median = n % 2 ? ms[n / 2] : 0.5 * (ms[n / 2 - 1] + ms[n / 2]);
  return t;
}

}  // namespace strata

namespace strata {

Effect parseEffect(const std::string& name) {
  if (name == "transparency") return Effect::Transparency;
  if (name == "translucency") return Effect::Translucency;
  throw Error("unknown effect '" + name + "' (known: transparency, translucency)");
}

std::string effectName(Effect e) {
  return e == Effect::Translucency ? "translucency" : "transparency";
}

}  // namespace strata
