#include "engine/cl_renderer.h"

#include "engine/cl_pipeline.h"

namespace strata {

namespace {

class ClRenderer final : public Renderer {
 public:
  ClRenderer(Method method, std::unique_ptr<ClMethod> impl, const DeviceOptions& device)
      : pipeline_(method, std::move(impl), device) {}
  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) override {
    return pipeline_.render(geometry, settings);
  }

 private:
  ClPipeline pipeline_;
};

std::unique_ptr<ClMethod> makeMethod(Method method) {
  switch (method) {
    case Method::Opaque: return makeOpaqueMethod();
    case Method::Ppll: return makePpllMethod();
    case Method::Abuffer: return makeAbufferMethod();
    case Method::Mdts: return makeMdtsMethod(false);
    case Method::Mdts32: return makeMdtsMethod(true);
    case Method::Dp: return makeDepthPeelingMethod(false);
    case Method::Ddp: return makeDepthPeelingMethod(true);
    case Method::Bdp: return makeBucketPeelingMethod(false);
    case Method::Bdp2: return makeBucketPeelingMethod(true);
    default: throw Error("method " + methodName(method) + " is not an OpenCL method");
  }
}

}  // namespace

std::unique_ptr<Renderer> makeClRenderer(Method method, const DeviceOptions& device) {
  if (method == Method::Cells) return makeCellsRenderer(device);
  return std::make_unique<ClRenderer>(method, makeMethod(method), device);
}

}  // namespace strata
