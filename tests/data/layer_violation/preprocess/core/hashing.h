// The base layer must not see OpenCL.
#include <CL/opencl.hpp>
