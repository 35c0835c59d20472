#include "engine/frontend/cl_renderer.h"

#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class ClRenderer final : public MethodRenderer {
 public:
  ClRenderer(Method method, std::unique_ptr<ClMethod> impl, const DeviceOptions& device)
      : pipeline_(method, std::move(impl), device) {}
  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) override {
    return pipeline_.render(geometry, settings);
  }

 private:
  ClPipeline pipeline_;
};

}  // namespace

std::unique_ptr<MethodRenderer> makeClRenderer(Method method, std::unique_ptr<ClMethod> impl,
                                               const DeviceOptions& device) {
  return std::make_unique<ClRenderer>(method, std::move(impl), device);
}

}  // namespace strata
