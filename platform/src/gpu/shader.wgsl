// The CPU rasterizer's shading model on the GPU: clip = matrix * position (the model origin is
// already added, in i64, before the f32 conversion, as the float pipeline does), colour and fog
// interpolated linearly in screen space, texture coordinates perspective-correct (or linear for
// `Perspective::Affine`), colour = texel * shade colour, then blended towards the fog colour by the
// per-vertex fog factor (1 = no fog).

struct Draw {
    matrix: mat4x4<f32>,
    // rgb: the flat colour, used when `flags.x` (Gouraud) is 0.
    flat_color: vec4<f32>,
    // rgb: the fog colour.
    fog_color: vec4<f32>,
    // x: fog start, y: fog end (eye distance, the clip w), z: 1 with fog.
    fog: vec4<f32>,
    // x: Gouraud shading, y: affine texture coordinates.
    flags: vec4<u32>,
};

@group(0) @binding(0) var<uniform> draw: Draw;
@group(0) @binding(1) var texels: texture_2d<f32>;
@group(0) @binding(2) var texel_sampler: sampler;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) color: vec4<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(linear) uv_affine: vec2<f32>,
    @location(2) @interpolate(linear) color: vec3<f32>,
    @location(3) @interpolate(linear) fog: f32,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = draw.matrix * vec4<f32>(v.position, 1.0);
    out.uv = v.uv;
    out.uv_affine = v.uv;
    out.color = select(draw.flat_color.rgb, v.color.rgb, draw.flags.x != 0u);
    let w = max(out.clip.w, 1e-30);
    var fog = 1.0;
    if draw.fog.z != 0.0 {
        if draw.fog.y > draw.fog.x {
            fog = clamp((draw.fog.y - w) / (draw.fog.y - draw.fog.x), 0.0, 1.0);
        } else {
            fog = select(0.0, 1.0, w < draw.fog.y);
        }
    }
    out.fog = fog;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let uv = select(in.uv, in.uv_affine, draw.flags.y != 0u);
    // Untextured draws bind a white texel, so one path serves both.
    let texel = textureSample(texels, texel_sampler, uv).rgb;
    let rgb = mix(draw.fog_color.rgb, texel * in.color, in.fog);
    return vec4<f32>(rgb, 1.0);
}
