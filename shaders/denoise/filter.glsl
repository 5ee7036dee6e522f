// The denoiser's filter, shared by its passes (temporal.comp, spatial*.comp) and twinned on the
// CPU by src/shading/denoise.rs, operation for operation.
//
// Spatial: a traced value (a light's visibility, or ambient occlusion's openness) averaged over
// a disc of taps as wide as half the penumbra the rays' blockers imply there (the width a light
// of its size casts past a blocker at the mean distance its rays hit; for occlusion, the mean
// distance itself: the scale over which what its rays hit changes), seen from the camera in
// pixels, narrowed as 1 / sqrt(frames) as the history grows, so that a still view converges to
// the rays' own mean. Taps on another surface (off the pixel's tangent plane by more than two
// pixels' width there, or turned away by more than about 25 degrees) weigh nothing, so the
// filter does not cross depth or crease edges; where no ray around found a blocker the pixel is
// left as traced, and where every tap agrees (all lit, all shadowed) the weighted mean is that
// value exactly.
//
// A source texel's y: the blockers' mean distance (0: no ray hit one); DENOISE_UNKNOWN (-1): no
// ray counted (the pixel takes its neighbours' value); DENOISE_FIXED (-2): the value holds as it
// is (a rect that cannot light the point: behind it, or below its horizon), and no neighbour
// takes it.
#ifndef UMBRA_DENOISE_GLSL
#define UMBRA_DENOISE_GLSL

// Taps of the disc (a Vogel spiral of 16 points), in 4 rotations that successive frames take in
// turn. Twin: shading::denoise::TAPS.
const vec2 DENOISE_TAPS[64] = vec2[](
    vec2(0.176777, 0.000000), vec2(-0.225772, 0.206826), vec2(0.034558, -0.393771), vec2(0.284571, 0.371173), vec2(-0.522223, -0.092374), vec2(0.494695, -0.314685), vec2(-0.165466, 0.615525), vec2(-0.315562, -0.607594), vec2(0.684642, 0.250030), vec2(-0.712256, 0.294009), vec2(0.343354, -0.733729), vec2(0.253731, 0.808932), vec2(-0.764746, -0.443186), vec2(0.897134, -0.197233), vec2(-0.547507, 0.778772), vec2(-0.126487, -0.976090),
    vec2(0.099814, 0.145901), vec2(-0.298181, -0.069558), vec2(0.344508, -0.193815), vec2(-0.145665, 0.444445), vec2(-0.218626, -0.483170), vec2(0.539044, 0.230610), vec2(-0.601446, 0.210981), vec2(0.323295, -0.603515), vec2(0.180213, 0.706239), vec2(-0.644822, -0.421846), vec2(0.799446, -0.130905), vec2(-0.524379, 0.666165), vec2(-0.066023, -0.881414), vec2(0.669337, 0.629077), vec2(-0.951894, -0.012157), vec2(0.734188, -0.655529),
    vec2(-0.064059, 0.164762), vec2(-0.110954, -0.285375), vec2(0.354485, 0.174902), vec2(-0.449067, 0.130726), vec2(0.275336, -0.453255), vec2(0.114031, 0.575106), vec2(-0.513729, -0.377270), vec2(0.680649, -0.073937), vec2(-0.481133, 0.547504), vec2(-0.015922, -0.770387), vec2(0.559436, 0.585902), vec2(-0.845896, -0.056652), vec2(0.690188, -0.552169), vec2(-0.141272, 0.907630), vec2(-0.527439, -0.792501), vec2(0.955583, 0.235820),
    vec2(-0.172155, 0.040159), vec2(0.172883, -0.252708), vec2(0.055801, 0.391326), vec2(-0.361452, -0.296820), vec2(0.529554, -0.028678), vec2(-0.410272, 0.418840), vec2(0.021308, -0.637021), vec2(0.445341, 0.520020), vec2(-0.723542, -0.087959), vec2(0.626842, -0.448129), vec2(-0.167692, 0.792546), vec2(-0.430866, -0.730140), vec2(0.845432, 0.257867), vec2(-0.828871, 0.395882), vec2(0.356274, -0.882791), vec2(0.344923, 0.921834)
);
const uint DENOISE_TAP_COUNT = 16u;
// How far (pixels) the first DENOISE_SEARCH_TAPS taps look for blockers (the spiral's first 8
// points reach 0.73 of its radius).
const float DENOISE_SEARCH = 10.0;
const uint DENOISE_SEARCH_TAPS = 8u;
// The filter's radius as a share of the penumbra's width.
const float DENOISE_WIDTH_SHARE = 0.5;
// The widest the filter gets (pixels).
const float DENOISE_MAX_RADIUS = 16.0;
// Below this radius (pixels) the pixel is left as traced.
const float DENOISE_MIN_RADIUS = 1.0;
// How far (pixels) a pixel none of whose rays counted (blocker -1) looks for its visibility.
const float DENOISE_UNKNOWN_RADIUS = 3.0;

// Tap `i` of rotation `rotation` at `radius` pixels from `px`, in whole pixels.
ivec2 denoise_tap(ivec2 px, uint rotation, uint i, float radius) {
    return px + ivec2(roundEven(DENOISE_TAPS[rotation * DENOISE_TAP_COUNT + i] * radius));
}

const float DENOISE_UNKNOWN = -1.0;
const float DENOISE_FIXED = -2.0;

// Width (world units) of the penumbra a sphere of radius `size` at `distance` from the point
// casts past a blocker `blocker` along the rays: 2 R b / (D - b).
float denoise_sphere_width(float size, float distance, float blocker) {
    return 2.0 * size * blocker / max(distance - blocker, 1e-3 * distance);
}

// A sun of angular radius `size` (radians' tangent): 2 b tan(half its angle).
float denoise_sun_width(float size, float blocker) {
    return 2.0 * blocker * size;
}

// The filter's radius (pixels) for a penumbra `width` wide at a point whose pixels are
// `footprint` wide, whose value is the mean of `rays` rays (over its history's frames): the
// noise falls as 1 / sqrt(rays), and so does the radius.
float denoise_radius(float width, float footprint, float rays) {
    return min(DENOISE_WIDTH_SHARE * width / footprint, DENOISE_MAX_RADIUS) / sqrt(max(rays, 1.0));
}

// How much a tap on the surface at `q` (position, > 0 w: drawn) with unit normal `nq` counts
// for the pixel at `p` with unit normal `n`, whose pixels are `footprint` wide there.
float denoise_tap_weight(vec3 p, vec3 n, float footprint, vec4 q, vec3 nq) {
    if (q.w <= 0.0) return 0.0;
    float plane = abs(dot(n, q.xyz - p));
    float along = max(1.0 - plane / (2.0 * footprint), 0.0);
    float c = max(dot(n, nq), 0.0);
    float c2 = c * c;
    float c4 = c2 * c2;
    float c8 = c4 * c4;
    return along * c8 * c8;
}

#endif
