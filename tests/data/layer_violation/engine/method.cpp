// A method that depends on the benchmark layer above it.
#include "engine/frontend/cl_pipeline.h"
#include "engine/report/bench.h"
