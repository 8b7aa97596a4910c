// Quadric simplification with OpenMesh (see ms_simplify.h). The only C++ unit.
#include "ms_simplify.h"

// GCC 12 reports a false maybe-uninitialized inside OpenMesh's own templates
// (std::vector of VectorT); it is not in this file's code.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <cstdlib>
#include <cstring>
#include <new>
#include <vector>

namespace {

typedef OpenMesh::TriMesh_ArrayKernelT<> TriMesh;

// Silences OpenMesh's error stream for the lifetime of the object.
struct QuietOpenMesh {
    bool was_enabled;
    QuietOpenMesh() : was_enabled(omerr().is_enabled()) { omerr().disable(); }
    ~QuietOpenMesh()
    {
        if (was_enabled)
            omerr().enable();
    }
};

ms_status simplify(const ms_mesh *in, size_t target, ms_mesh *out, ms_simplify_report *report, ms_error *err)
{
    QuietOpenMesh quiet;
    TriMesh mesh;
    mesh.reserve(in->vertex_count, 3 * in->triangle_count, in->triangle_count);
    std::vector<TriMesh::VertexHandle> vh(in->vertex_count);
    for (size_t i = 0; i < in->vertex_count; ++i)
        vh[i] = mesh.add_vertex(TriMesh::Point(in->positions[3 * i], in->positions[3 * i + 1],
                                               in->positions[3 * i + 2]));
    for (size_t t = 0; t < in->triangle_count; ++t) {
        const uint32_t *v = &in->triangles[3 * t];
        if (v[0] >= in->vertex_count || v[1] >= in->vertex_count || v[2] >= in->vertex_count)
            return ms_error_set(err, MS_ERR_ARG, "simplify: triangle %zu has a bad vertex index", t);
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2] || !mesh.add_face(vh[v[0]], vh[v[1]], vh[v[2]]).is_valid())
            report->refused_faces++;
    }
    if (mesh.n_faces() == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "simplify: no usable triangle");
    if (mesh.n_faces() > target) {
        OpenMesh::Decimater::DecimaterT<TriMesh> decimater(mesh);
        OpenMesh::Decimater::ModQuadricT<TriMesh>::Handle quadric;
        decimater.add(quadric);
        decimater.module(quadric).unset_max_err();
        decimater.initialize();
        decimater.decimate_to_faces(0, target);
        mesh.garbage_collection();
    }
    out->positions = static_cast<double *>(malloc((3 * mesh.n_vertices() + 1) * sizeof(double)));
    out->triangles = static_cast<uint32_t *>(malloc((3 * mesh.n_faces() + 1) * sizeof(uint32_t)));
    if (!out->positions || !out->triangles) {
        ms_mesh_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "simplify: no memory for the result");
    }
    for (TriMesh::VertexIter it = mesh.vertices_begin(); it != mesh.vertices_end(); ++it) {
        const TriMesh::Point &p = mesh.point(*it);
        for (int a = 0; a < 3; ++a)
            out->positions[3 * it->idx() + a] = p[a];
    }
    size_t t = 0;
    for (TriMesh::FaceIter it = mesh.faces_begin(); it != mesh.faces_end(); ++it, ++t) {
        int k = 0;
        for (TriMesh::FaceVertexIter fv = mesh.fv_iter(*it); fv.is_valid() && k < 3; ++fv, ++k)
            out->triangles[3 * t + k] = static_cast<uint32_t>(fv->idx());
    }
    out->vertex_count = out->vertex_capacity = mesh.n_vertices();
    out->triangle_count = out->triangle_capacity = mesh.n_faces();
    report->output_triangles = out->triangle_count;
    report->output_vertices = out->vertex_count;
    return MS_OK;
}

} // namespace

extern "C" ms_status ms_simplify(const ms_mesh *in, size_t target_triangles, ms_mesh *out,
                                 ms_simplify_report *report, ms_error *err)
{
    ms_simplify_report local;
    if (!report)
        report = &local;
    std::memset(report, 0, sizeof *report);
    std::memset(out, 0, sizeof *out);
    report->input_triangles = in->triangle_count;
    if (target_triangles == 0)
        return ms_error_set(err, MS_ERR_ARG, "simplify: target of 0 triangles");
    try {
        return simplify(in, target_triangles, out, report, err);
    } catch (const std::bad_alloc &) {
        ms_mesh_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "simplify: out of memory");
    } catch (...) {
        ms_mesh_free(out);
        return ms_error_set(err, MS_ERR_FORMAT, "simplify: OpenMesh failed");
    }
}
