#pragma once
// The camera panel: the whole image scaled into the panel with its aspect kept (never cropped,
// never scrolled), the depth preview beside it, the velocity and marker overlays on it.

#include "hq/console/console_model.hpp"

namespace hq::console {

/// A rectangle in pixels.
struct PixelRect {
  float x = 0;
  float y = 0;
  float width = 0;
  float height = 0;
};

/// The largest rectangle of an image_width x image_height image's aspect inside `area`,
/// centred in it (letterboxed). Empty for an empty area or image.
PixelRect fit_image(const PixelRect& area, int image_width_px, int image_height_px);

/// A decoded image on the GPU: its GL texture name and size (0: none yet).
struct ImageTexture {
  unsigned int id = 0;
  int width_px = 0;
  int height_px = 0;
};

/// What the panel reports back for the window's stats.
struct CameraPanelResult {
  PixelRect image{};         ///< Where the camera image was drawn (screen pixels).
  bool image_whole = false;  ///< Drawn entirely inside the panel's visible area.
};

/// Draws the "Camera" window's content (the caller places the window). `video_line` is the
/// latency line under the image ("" for none).
CameraPanelResult draw_camera_panel(const Snapshot& s, const ImageTexture& camera,
                                    const ImageTexture& depth, const char* video_line,
                                    const char* size_line);

}  // namespace hq::console
