// The image library strata reads and writes images with: OpenImageIO where the build has it
// (STRATA_WITH_OPENIMAGEIO), else stb_image and stb_image_write.
#pragma once

#if STRATA_WITH_OPENIMAGEIO
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#else
#include <stb_image.h>
#include <stb_image_write.h>
#endif
