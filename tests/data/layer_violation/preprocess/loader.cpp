// A loader that reaches up into the renderer: the layer check must refuse it.
#include "preprocess/scene/scene.h"
#include "engine/renderer.h"
