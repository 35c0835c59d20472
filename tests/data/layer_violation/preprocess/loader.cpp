// A loader that reaches up into the renderer: the layer check must refuse it.
#include "engine/renderer.h"
#include "preprocess/scene/scene.h"
