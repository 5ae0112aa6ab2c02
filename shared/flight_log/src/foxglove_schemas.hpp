#pragma once
/// JSON Schemas of the link log's Foxglove JSON channels, following Foxglove's schemas
/// (https://docs.foxglove.dev/docs/visualization/message-schemas): with message encoding "json"
/// bytes fields are base64 strings, which is what Foxglove's Image and 3D panels decode.

namespace hq::flight_log {

inline constexpr const char* kTimeSchema =
    R"j({"type":"object","properties":{"sec":{"type":"integer","minimum":0},)j"
    R"j("nsec":{"type":"integer","minimum":0,"maximum":999999999}}})j";

inline constexpr const char* kCompressedImageSchema =
    R"j({"title":"foxglove.CompressedImage","description":"A compressed image","type":"object",)j"
    R"j("properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},)j"
    R"j("nsec":{"type":"integer"}}},"frame_id":{"type":"string"},)j"
    R"j("data":{"type":"string","contentEncoding":"base64"},"format":{"type":"string"}}})j";

inline constexpr const char* kPointCloudSchema =
    R"j({"title":"foxglove.PointCloud","description":"A collection of N-dimensional points",)j"
    R"j("type":"object","properties":{"timestamp":{"type":"object","properties":{)j"
    R"j("sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},)j"
    R"j("pose":{"type":"object","properties":{"position":{"type":"object","properties":{)j"
    R"j("x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},)j"
    R"j("orientation":{"type":"object","properties":{"x":{"type":"number"},)j"
    R"j("y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}},)j"
    R"j("point_stride":{"type":"integer","minimum":0},"fields":{"type":"array","items":{)j"
    R"j("type":"object","properties":{"name":{"type":"string"},"offset":{"type":"integer"},)j"
    R"j("type":{"type":"integer"}}}},"data":{"type":"string","contentEncoding":"base64"}}})j";

// foxglove.FrameTransform (https://docs.foxglove.dev/docs/sdk/schemas/frame-transform).
inline constexpr const char* kFrameTransformSchema =
    R"j({"title":"foxglove.FrameTransform","description":"A transform between two reference )j"
    R"j(frames in 3D space","type":"object","properties":{"timestamp":{"type":"object",)j"
    R"j("properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},)j"
    R"j("parent_frame_id":{"type":"string"},"child_frame_id":{"type":"string"},)j"
    R"j("translation":{"type":"object","properties":{"x":{"type":"number"},)j"
    R"j("y":{"type":"number"},"z":{"type":"number"}}},"rotation":{"type":"object",)j"
    R"j("properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},)j"
    R"j("w":{"type":"number"}}}}})j";

// foxglove.CameraCalibration (https://docs.foxglove.dev/docs/sdk/schemas/camera-calibration).
inline constexpr const char* kCameraCalibrationSchema =
    R"j({"title":"foxglove.CameraCalibration","description":"Camera calibration parameters",)j"
    R"j("type":"object","properties":{"timestamp":{"type":"object","properties":{)j"
    R"j("sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},)j"
    R"j("width":{"type":"integer","minimum":0},"height":{"type":"integer","minimum":0},)j"
    R"j("distortion_model":{"type":"string"},"D":{"type":"array","items":{"type":"number"}},)j"
    R"j("K":{"type":"array","items":{"type":"number"},"minItems":9,"maxItems":9},)j"
    R"j("R":{"type":"array","items":{"type":"number"},"minItems":9,"maxItems":9},)j"
    R"j("P":{"type":"array","items":{"type":"number"},"minItems":12,"maxItems":12}}})j";

inline constexpr const char* kVector3Schema =
    R"j({"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},)j"
    R"j("z":{"type":"number"}}})j";

}  // namespace hq::flight_log
