// sirad: writing a solution as the four outputs of DESIGN.md section 4 (NAME.exr, NAME.png,
// NAME.ply, NAME.glb), shared by every driver (single node, coordinator, farm).
#pragma once
#include <string>
#include <vector>

#include "io/write.h"
#include "render/gather.h"

namespace sirad {

struct ResultOptions {
  int width = 512, height = 512;
  Shading shading = Shading::gouraud;
  float exposure = 0.0f;
  // Samples per pixel side for the images (anti-aliasing); 0: 4 (16 per pixel) up to 1024
  // pixels a side, fewer above (the finer image stays within 4096 a side), 1 above 2048.
  int samples_per_side = 0;
  // > 0: the images are a final gather (render/gather.h, its default seed) with this many samples
  // per pixel, the EXR with its passes; 0: the patches drawn.
  int final_gather_spp = 0;
};

// The final gather the options ask for (spp 0: none): the image's size and samples, the
// gather's default seed. A cluster run renders it in tiles (cluster::RunConfig::final_gather).
GatherOptions final_gather_of(const ResultOptions& options);

struct ResultFiles {
  std::string exr, png, ply, glb;
};

// "wrote PATH" for each file, absolute, one a line.
std::string wrote_lines(const ResultFiles& files);

// Fails early, before any work, if NAME's directory does not exist or is not writable; the
// message names it by `flag` (what gave the name).
void check_output_name(const std::string& name, const std::string& flag);
// The same for a file written whole at `path` itself (a checkpoint, a ledger, a status file, a
// key): also refused when `path` is a directory.
void check_file_name(const std::string& path, const std::string& flag);

// Writes NAME.exr, .png, .ply and .glb atomically: the image is the patches drawn from the mesh's
// camera, or with options.final_gather_spp > 0 `gathered`, the final gather's passes the caller
// rendered (a cluster run's tiles: RunResult::image; one machine's: cli write_outputs), of the
// options' size.
// A solution outlives its image: where the image cannot be made (`image_failed` says why, as a
// cluster run's RunResult::image_error does, or rendering it here fails or runs out of memory),
// NAME.ply and NAME.glb are still written, together, and then an Error names the image's
// failure and the files kept.
ResultFiles write_results(const std::string& name, const PatchMesh& mesh,
                          const std::vector<glm::vec3>& radiosity, const ResultOptions& options,
                          const Attributes& attributes, const GatherPasses* gathered = nullptr,
                          const std::string& image_failed = {});

}  // namespace sirad
