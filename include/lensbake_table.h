/*
 * lensbake_table.h: the layout of a lensbake lens ray transfer function (LRTF) table, for
 * engines that read one without lensbake. Plain C99; no lensbake code needed.
 * tests/table_header.rs compiles it and checks every number and offset against lensbake's own.
 * The method and its reasons are in docs/lrtf.md; binding the exported sampler in docs/engines.md.
 *
 * A table is a directory of two files:
 *   lrtf.ron  the sidecar (RON; its fields as JSON Schema in docs/lrtf-sidecar.schema.json):
 *             what the numbers mean, the domain, the pupil circles, the checksums.
 *   lrtf.exr  the entries: OpenEXR, uncompressed scanlines, one part per wavelength layer, the
 *             part named "wl<k>" (k = 0, 1, ...: the sidecar's layers[k].exr_layer) and its
 *             channels named "wl<k>.<channel>" (LENSBAKE_CHANNEL_NAMES below), HALF or FLOAT
 *             samples as the sidecar's info.precision says ("F16" or "F32"); for "U16",
 *             UINT samples holding 16-bit codes: channel c of code q is the f32
 *             layers[k].quantisation.low[c] + layers[k].quantisation.step[c] * q (a multiply,
 *             then an add, in f32), decoded per node before the trilinear weights.
 *
 * Conventions: lengths in mm, angles in radians, wavelengths in nm. Lens frame: z is the optical
 * axis, light travels towards +z, origin at the vertex of surface 1. Film-side rays start behind
 * the lens (at larger z) and travel -z; the table gives the ray leaving surface 1 into the scene.
 * Values are stored in a canonical frame: rotated about z so the film point (pupil-planes) or
 * the rear-plane point (spherical) lies on +x, and mirrored y -> -y where the ray's canonical y
 * is negative; the sampler rotates and mirrors them back.
 *
 * Nodes: a layer holds n0 x n1 x n2 nodes (the sidecar's info.resolution); node k of an axis of
 * n nodes sits at table coordinate k / (n - 1), both ends sampled. In lrtf.exr a layer is an
 * image of n0 x (n1 * n2) pixels: pixel (x, y) is node (i0 = x, i1 = y mod n1, i2 = y div n1).
 * Lookups are trilinear over the 8 nodes of the cell (no hardware filtering).
 */
#ifndef LENSBAKE_TABLE_H
#define LENSBAKE_TABLE_H

#include <stddef.h>
#include <stdint.h>

/* The sidecar's format_version this header describes, and the oldest lensbake still reads
 * (format 4 names channels without the "wl<k>." prefix). The exported shaders carry the same
 * number in LrtfParams.format_version and answer LENSBAKE_LRTF_VERSION_MISMATCH otherwise. */
#define LENSBAKE_TABLE_FORMAT_VERSION 5u
#define LENSBAKE_TABLE_OLDEST_FORMAT_VERSION 4u

/* Channels per node, in storage order. */
#define LENSBAKE_TABLE_CHANNELS 8

enum lensbake_channel {
    /* Where the ray leaves surface 1, canonical x and y (mm). */
    LENSBAKE_CHANNEL_EXIT_X = 0,
    LENSBAKE_CHANNEL_EXIT_Y = 1,
    /* Outgoing direction: pupil-planes, stereographic (a, b) with direction
     * (2a, 2b, -(1 - a^2 - b^2)) / (1 + a^2 + b^2); spherical, (polar angle from -z, azimuth). */
    LENSBAKE_CHANNEL_DIR_A = 2,
    LENSBAKE_CHANNEL_DIR_B = 3,
    /* Signed aperture margin: the ray clears every aperture the stop test does not cover where
     * the interpolated margin is >= 0 (mm). */
    LENSBAKE_CHANNEL_MARGIN = 4,
    /* Where the ray crosses the stop surface, canonical x and y (mm): the f-number test
     * stop.x^2 + stop.y^2 <= stop_radius^2. */
    LENSBAKE_CHANNEL_STOP_X = 5,
    LENSBAKE_CHANNEL_STOP_Y = 6,
    /* z of the exit point on surface 1 (mm, lens frame). */
    LENSBAKE_CHANNEL_EXIT_Z = 7
};

/* EXR channel names after the layer prefix: layer k's channel c is "wl<k>." + this. */
#define LENSBAKE_CHANNEL_NAMES \
    { "exit.x", "exit.y", "dir.a", "dir.b", "margin", "stop.x", "stop.y", "exit.z" }

/* On the GPU the eight channels are two RGBA f32 3D textures: texture 0 holds channels 0-3,
 * texture 1 channels 4-7. */
#define LENSBAKE_TEXTURE0_FIRST_CHANNEL LENSBAKE_CHANNEL_EXIT_X
#define LENSBAKE_TEXTURE1_FIRST_CHANNEL LENSBAKE_CHANNEL_MARGIN

/* LrtfParams.parameterisation (the sidecar's info.parameterisation). */
#define LENSBAKE_PARAMETERISATION_SPHERICAL 0u
#define LENSBAKE_PARAMETERISATION_PUPIL_PLANES 1u

/* LrtfResult.status of the sampler. */
#define LENSBAKE_LRTF_PASSES 0u
#define LENSBAKE_LRTF_BLOCKED 1u
#define LENSBAKE_LRTF_OUTSIDE 2u
#define LENSBAKE_LRTF_VERSION_MISMATCH 3u

/* The sampler's uniform block LrtfParams (std140, 64 bytes), filled from the sidecar:
 *   rear_plane_z, film_plane_z, max_film_radius, max_rear_radius, max_polar_angle:
 *       layers[0].frame (the film plane and film radius the coordinates are normalised on);
 *   stop_radius_sq: (layers[0].stop_semi_aperture * info.f_number / wanted f-number)^2;
 *   pupil_count: layers[0].pupil.circles length (circles at film radii
 *       max_film_radius * k / (pupil_count - 1));
 *   dims: info.resolution;
 *   sampling_max_film_radius, sampling_count, focus_count: layers[0].sampling_pupil (its
 *       nodes' max_film_radius, circles per node, node count);
 *   focus_coordinate: the render's film plane z in focus-node units,
 *       clamp((z - film_z[0]) / (film_z[1] - film_z[0]), 0, 1) * (focus_count - 1), 0 for one
 *       node; z for an object d mm in front of surface 1 is
 *       info.focus.rear_focal_z + info.focus.focal_product / (info.focus.front_focal_z + d). */
typedef struct lensbake_lrtf_params {
    float rear_plane_z;
    float film_plane_z;
    float max_film_radius;
    float max_rear_radius;
    float max_polar_angle;
    float stop_radius_sq;
    uint32_t parameterisation;
    uint32_t pupil_count;
    uint32_t dims[3];
    uint32_t format_version;
    float sampling_max_film_radius;
    uint32_t sampling_count;
    uint32_t focus_count;
    float focus_coordinate;
} lensbake_lrtf_params;

typedef char lensbake_lrtf_params_is_64_bytes[sizeof(lensbake_lrtf_params) == 64 ? 1 : -1];

/* One effective-pupil circle on the rear plane, canonical frame (mm). The sampler's circle
 * buffer holds each layer's coordinate circles (block k of pupil_count for layer k), then the
 * sampling pupil: focus_count rows of sampling_count circles. */
typedef struct lensbake_pupil_circle {
    float centre_x;
    float radius;
} lensbake_pupil_circle;

/* Index of node (i0, i1, i2) of layer `layer` in the textures (x fastest, layers stacked along
 * z), and equally of pixel (i0, i1 + n1 * i2) in that layer's EXR part. */
static inline size_t lensbake_node_index(const uint32_t dims[3], uint32_t layer, uint32_t i0,
                                         uint32_t i1, uint32_t i2)
{
    return (size_t)i0 + (size_t)dims[0] * ((size_t)i1 + (size_t)dims[1] *
                                           ((size_t)i2 + (size_t)dims[2] * layer));
}

#endif /* LENSBAKE_TABLE_H */
