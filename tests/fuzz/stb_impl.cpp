// The stb implementations, compiled here with the harnesses' instrumentation (Debian's libstb is not), so
// the PNG harness fuzzes the decoder itself and the sanitizers see inside it.
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb_image.h>
#include <stb_image_write.h>
