/* The study scene's layout, shared by the scene, the renderer and the measures
 * (server/study only). See ms_study_scene.h. */
#ifndef MS_STUDY_SCENE_INTERNAL_H
#define MS_STUDY_SCENE_INTERNAL_H

#include <embree3/rtcore.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_study_scene.h"

struct ms_study_scene {
    RTCDevice device;
    RTCScene rtc;
    double origin[3];      /* world position of the local frame's origin */
    double *local;         /* 3 per vertex: world - origin, doubles */
    float *local_f;        /* 3 per vertex + 1 float of padding (Embree's 16-byte loads) */
    uint32_t *triangles;   /* 3 per triangle */
    double *face_normal;   /* 3 per triangle: unit, as oriented; 0 for a degenerate one */
    double *vertex_normal; /* 3 per vertex: area-weighted mean of its faces' normals, unit (0 if none) */
    size_t vertex_count, triangle_count;
    double lo[3], hi[3];   /* world bounds */
};

#endif
