// Cache generator benchmark: median time and peak memory on Sponza (lod4, 187k triangles,
// normals computed as a loader would) at a d_eps giving 5,000-10,000 caches, and on the
// procedural 1M-triangle street. Run by `make bench`.
#define GIMANY_IMPLEMENTATION
#define GIMANY_NO_GL
#include "gimany.h"
#include "street.h"

#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define STB_IMAGE_IMPLEMENTATION
#include <tiny_gltf.h>

#include <sys/resource.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

namespace {

struct Counter {
    size_t bytes = 0, peak = 0;
    long live = 0;
};
void *count_alloc(size_t n, void *u) {
    Counter *c = static_cast<Counter *>(u);
    size_t *p = static_cast<size_t *>(std::malloc(n + 16));
    if (!p) return nullptr;
    p[0] = n;
    c->bytes += n;
    c->live++;
    c->peak = std::max(c->peak, c->bytes);
    return p + 2;
}
void count_free(void *q, void *u) {
    Counter *c = static_cast<Counter *>(u);
    size_t *p = static_cast<size_t *>(q) - 2;
    c->bytes -= p[0];
    c->live--;
    std::free(p);
}

struct Mesh {
    std::vector<float> pos, nrm;
    std::vector<uint32_t> idx;
};

// Column-major 4x4 product.
void mat_mul(const double *a, const double *b, double *r) {
    for (int c = 0; c < 4; ++c)
        for (int rr = 0; rr < 4; ++rr) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += a[k * 4 + rr] * b[c * 4 + k];
            r[c * 4 + rr] = s;
        }
}

void node_matrix(const tinygltf::Node &n, double *m) {
    for (int i = 0; i < 16; ++i) m[i] = (i % 5 == 0) ? 1.0 : 0.0;
    if (n.matrix.size() == 16) {
        for (int i = 0; i < 16; ++i) m[i] = n.matrix[i];
        return;
    }
    double t[16], r[16], s[16], tr[16];
    for (int i = 0; i < 16; ++i) t[i] = r[i] = s[i] = (i % 5 == 0) ? 1.0 : 0.0;
    if (n.translation.size() == 3) { t[12] = n.translation[0]; t[13] = n.translation[1]; t[14] = n.translation[2]; }
    if (n.scale.size() == 3) { s[0] = n.scale[0]; s[5] = n.scale[1]; s[10] = n.scale[2]; }
    if (n.rotation.size() == 4) {
        double x = n.rotation[0], y = n.rotation[1], z = n.rotation[2], w = n.rotation[3];
        r[0] = 1 - 2 * (y * y + z * z); r[1] = 2 * (x * y + z * w); r[2] = 2 * (x * z - y * w);
        r[4] = 2 * (x * y - z * w); r[5] = 1 - 2 * (x * x + z * z); r[6] = 2 * (y * z + x * w);
        r[8] = 2 * (x * z + y * w); r[9] = 2 * (y * z - x * w); r[10] = 1 - 2 * (x * x + y * y);
    }
    mat_mul(t, r, tr);
    mat_mul(tr, s, m);
}

// Triangles of every node's mesh, in world space.
void add_node(const tinygltf::Model &model, int ni, const double *parent, Mesh &out) {
    const tinygltf::Node &node = model.nodes[ni];
    double local[16], world[16];
    node_matrix(node, local);
    mat_mul(parent, local, world);
    if (node.mesh >= 0) {
        for (const tinygltf::Primitive &prim : model.meshes[node.mesh].primitives) {
            if (prim.mode != TINYGLTF_MODE_TRIANGLES && prim.mode != -1) continue;
            auto it = prim.attributes.find("POSITION");
            if (it == prim.attributes.end()) continue;
            const tinygltf::Accessor &pa = model.accessors[it->second];
            if (pa.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT || pa.type != TINYGLTF_TYPE_VEC3) continue;
            const tinygltf::BufferView &pv = model.bufferViews[pa.bufferView];
            const unsigned char *pb = model.buffers[pv.buffer].data.data() + pv.byteOffset + pa.byteOffset;
            size_t ps = pa.ByteStride(pv) > 0 ? (size_t)pa.ByteStride(pv) : 12u;
            uint32_t base = (uint32_t)(out.pos.size() / 3);
            for (size_t v = 0; v < pa.count; ++v) {
                float p[3];
                std::memcpy(p, pb + v * ps, 12);
                for (int k = 0; k < 3; ++k)
                    out.pos.push_back((float)(world[k] * p[0] + world[4 + k] * p[1] + world[8 + k] * p[2] + world[12 + k]));
            }
            if (prim.indices >= 0) {
                const tinygltf::Accessor &ia = model.accessors[prim.indices];
                const tinygltf::BufferView &iv = model.bufferViews[ia.bufferView];
                const unsigned char *ib = model.buffers[iv.buffer].data.data() + iv.byteOffset + ia.byteOffset;
                for (size_t i = 0; i < ia.count; ++i) {
                    uint32_t x = 0;
                    if (ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) std::memcpy(&x, ib + i * 4, 4);
                    else if (ia.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) { uint16_t s; std::memcpy(&s, ib + i * 2, 2); x = s; }
                    else x = ib[i];
                    out.idx.push_back(base + x);
                }
            } else {
                for (uint32_t i = 0; i < (uint32_t)pa.count; ++i) out.idx.push_back(base + i);
            }
        }
    }
    for (int c : node.children) add_node(model, c, world, out);
}

// Area-weighted vertex normals, as a loader does for a file without them.
void compute_normals(Mesh &m) {
    m.nrm.assign(m.pos.size(), 0.0f);
    for (size_t t = 0; t + 2 < m.idx.size(); t += 3) {
        const float *a = &m.pos[m.idx[t] * 3], *b = &m.pos[m.idx[t + 1] * 3], *c = &m.pos[m.idx[t + 2] * 3];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j) m.nrm[m.idx[t + k] * 3 + j] += n[j];
    }
    for (size_t v = 0; v < m.nrm.size(); v += 3) {
        float l = std::sqrt(m.nrm[v] * m.nrm[v] + m.nrm[v + 1] * m.nrm[v + 1] + m.nrm[v + 2] * m.nrm[v + 2]);
        if (l > 0) for (int j = 0; j < 3; ++j) m.nrm[v + j] /= l;
        else m.nrm[v + 2] = 1.0f;
    }
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

long maxrss_kb() {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss;
}

// Runs the generator `runs` times; prints median time, caches and peak memory.
bool run(const char *name, gim_cache_desc d, uint32_t triangles, int runs, uint32_t *count = nullptr) {
    std::vector<double> t;
    Counter c;
    gim_cache_set s;
    std::memset(&s, 0, sizeof s);
    d.env.allocator.alloc = count_alloc;
    d.env.allocator.free = count_free;
    d.env.allocator.user_data = &c;
    d.env.logger.func = gim_log_stderr;
    for (int r = 0; r < runs; ++r) {
        gim_cache_set_free(&s);
        auto t0 = std::chrono::steady_clock::now();
        gim_result res = gim_cache_generate(&d, &s);
        auto t1 = std::chrono::steady_clock::now();
        if (res != GIM_OK) {
            std::printf("%s: gim_cache_generate failed: %s\n", name, gim_result_string(res));
            return false;
        }
        t.push_back(std::chrono::duration<double>(t1 - t0).count());
    }
    std::printf("%-22s %8u tris  d_eps %-9.4g caches %6u (before merge %6u, snapped %6u, voxels %7u)\n", name, triangles,
                (double)s.d_eps, s.count, s.report.caches_before_merge, s.report.caches_snapped, s.report.voxels);
    std::printf("%-22s median %.3f s (min %.3f, %d runs)  peak alloc %.1f MiB (%.0f B/triangle)  maxrss %.1f MiB\n", "",
                median(t), *std::min_element(t.begin(), t.end()), runs, c.peak / 1048576.0, (double)c.peak / triangles,
                maxrss_kb() / 1024.0);
    if (count) *count = s.count;
    gim_cache_set_free(&s);
    return c.live == 0;
}

} // namespace

// Usage: bench_caches [runs] [sponza d_eps]
int main(int argc, char **argv) {
    bool ok = true;
    const int runs = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
    const float sponza_d_eps = argc > 2 ? (float)std::atof(argv[2]) : 3.4f;
    std::printf("cache generator (gim_cache_generate), single thread\n");

    // Sponza: d_eps 3.4 (scene units, the atrium is about 36 x 20 x 20) gives 5,000-10,000 caches.
    {
        const char *path = "../shared/scenes/sponza_lod4/sponza_lod4.glb";
        std::FILE *f = std::fopen(path, "rb");
        if (!f) {
            std::printf("sponza_lod4: %s not found, skipped\n", path);
        } else {
            std::fclose(f);
            tinygltf::Model model;
            tinygltf::TinyGLTF loader;
            std::string err, warn;
            Mesh m;
            if (!loader.LoadBinaryFromFile(&model, &err, &warn, path)) {
                std::printf("sponza_lod4: load failed: %s\n", err.c_str());
                return 1;
            }
            const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
            int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
            for (int n : model.scenes[scene].nodes) add_node(model, n, id, m);
            compute_normals(m);
            gim_cache_desc d;
            std::memset(&d, 0, sizeof d);
            d.mesh.positions = m.pos.data();
            d.mesh.vertex_count = (uint32_t)(m.pos.size() / 3);
            d.mesh.normals = m.nrm.data();
            d.mesh.indices = m.idx.data();
            d.mesh.index_count = (uint32_t)m.idx.size();
            d.d_eps = sponza_d_eps;
            uint32_t caches = 0;
            ok &= run("sponza_lod4", d, d.mesh.index_count / 3, runs, &caches);
            if (caches < 5000 || caches > 10000)
                std::printf("sponza_lod4: WARNING %u caches, outside the 5,000-10,000 this benchmark is for\n", caches);
        }
    }

    // The street: 1M triangles, default d_eps (scene diagonal / 32) and a finer one.
    {
        street_params sp;
        street_mesh sm;
        std::memset(&sp, 0, sizeof sp);
        sp.target_triangles = 1000000;
        if (street_build(&sp, &sm) != 0) {
            std::printf("street: build failed\n");
            return 1;
        }
        gim_cache_desc d;
        std::memset(&d, 0, sizeof d);
        d.mesh = street_mesh_data(&sm);
        ok &= run("street 1M (default)", d, sm.triangle_count, runs);
        d.d_eps = 1.0f;
        ok &= run("street 1M (d_eps 1 m)", d, sm.triangle_count, runs);
        street_free(&sm);
    }
    return ok ? 0 : 1;
}
