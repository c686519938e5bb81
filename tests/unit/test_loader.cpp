/* The glTF loader of the scene layer (scene/scene.cpp) against hostile files: deep JSON
   nesting, special files as the scene or as a buffer, a buffer's file far larger than its
   declared byteLength, a decompression-bomb PNG referenced 8 times, a node graph that
   expands exponentially. Each load runs in a child process with an alarm; the parent checks
   that it was refused (or loaded with the image skipped) within a bounded time and peak
   memory. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
extern "C" {
#include <cmocka.h>
}
#include "scene.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

namespace {

const int LIMIT_S = 30;               /* a load that takes longer is a hang */
const long LIMIT_KB = 1024L * 1024L;  /* peak RSS of the child, ASan's shadow included */

std::string dir;

void write_file(const std::string &name, const std::string &data) {
    FILE *f = std::fopen((dir + "/" + name).c_str(), "wb");
    assert_non_null(f);
    assert_int_equal(std::fwrite(data.data(), 1, data.size(), f), data.size());
    std::fclose(f);
}

std::string base64(const std::string &in) {
    static const char *t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string o;
    size_t i = 0;
    for (; i + 2 < in.size(); i += 3) {
        unsigned v = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8 | (unsigned char)in[i + 2];
        o += t[v >> 18]; o += t[(v >> 12) & 63]; o += t[(v >> 6) & 63]; o += t[v & 63];
    }
    if (i < in.size()) {
        unsigned v = (unsigned char)in[i] << 16 | (i + 1 < in.size() ? (unsigned char)in[i + 1] << 8 : 0);
        o += t[v >> 18]; o += t[(v >> 12) & 63];
        o += i + 1 < in.size() ? t[(v >> 6) & 63] : '=';
        o += '=';
    }
    return o;
}

/* One triangle's positions (36 bytes) as a data URI. */
std::string triangle_uri() {
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    return "data:application/octet-stream;base64," + base64(std::string(reinterpret_cast<const char *>(p), sizeof p));
}

/* A glTF: `nodes` and `scene_nodes` as given, mesh 0 the triangle from buffer_uri, `extra`
   spliced into the top-level object. */
std::string gltf(const std::string &nodes, const std::string &scene_nodes, const std::string &buffer_uri,
                 const std::string &extra = "") {
    return "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[" + scene_nodes + "]}],\"nodes\":[" + nodes +
           "],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}}]}],"
           "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
           "\"min\":[0,0,0],\"max\":[1,1,0]}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
           "\"buffers\":[{\"byteLength\":36,\"uri\":\"" + buffer_uri + "\"}]" + extra + "}";
}

struct outcome {
    int status;      /* the loader's return; -1: the child did not finish */
    double seconds;
    long peak_kb;
    std::string err;
};

/* scene_load_gltf(dir/name) in a child: its result, message, time and peak RSS. */
outcome load_in_child(const std::string &name) {
    int fd[2];
    assert_int_equal(pipe(fd), 0);
    struct timeval t0, t1;
    gettimeofday(&t0, nullptr);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        close(fd[0]);
        alarm(LIMIT_S);
        scene s;
        char err[512] = "";
        int r = scene_load_gltf((dir + "/" + name).c_str(), &s, err, sizeof err);
        if (r == 0) {
            std::snprintf(err, sizeof err, "loaded: %u meshes, %u warnings: %s", s.mesh_count, s.warning_count, s.warning);
            scene_free(&s);
        }
        char msg[520];
        int n = std::snprintf(msg, sizeof msg, "%d %s", r, err);
        if (write(fd[1], msg, (size_t)n) < 0) _exit(3);
        _exit(0);
    }
    close(fd[1]);
    outcome o;
    std::string text;
    char buf[256];
    ssize_t n;
    while ((n = read(fd[0], buf, sizeof buf)) > 0) text.append(buf, (size_t)n);
    close(fd[0]);
    int st = 0;
    struct rusage ru;
    std::memset(&ru, 0, sizeof ru);
    assert_int_equal(wait4(pid, &st, 0, &ru), pid);
    gettimeofday(&t1, nullptr);
    o.seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-6 * (double)(t1.tv_usec - t0.tv_usec);
    o.peak_kb = ru.ru_maxrss;
    o.status = -1;
    if (WIFEXITED(st) && WEXITSTATUS(st) == 0 && !text.empty()) {
        o.status = std::atoi(text.c_str());
        o.err = text.substr(text.find(' ') + 1);
    }
    std::printf("  %-22s -> %d in %.2f s, peak %ld MB: %s\n", name.c_str(), o.status, o.seconds, o.peak_kb / 1024,
                o.err.c_str());
    return o;
}

void expect_refused(const std::string &name, const char *why) {
    outcome o = load_in_child(name);
    assert_true(o.status > 0);
    assert_true(o.seconds < LIMIT_S && o.peak_kb < LIMIT_KB);
    if (!std::strstr(o.err.c_str(), why)) fail_msg("'%s' not in '%s'", why, o.err.c_str());
}

/* A well-formed file loads: the limits leave ordinary files alone. */
void ordinary_file_loads(void **) {
    write_file("ok.gltf", gltf("{\"mesh\":0}", "0", triangle_uri()));
    outcome o = load_in_child("ok.gltf");
    assert_int_equal(o.status, 0);
}

/* 16,000 levels of nested arrays in "extras" (the size that overflowed the parser's stack)
   and just above the limit; at the limit it parses. */
void deep_nesting(void **) {
    std::string deep = ",\"extras\":" + std::string(16000, '[') + std::string(16000, ']');
    write_file("deep.gltf", gltf("{\"mesh\":0}", "0", triangle_uri(), deep));
    expect_refused("deep.gltf", "more than 128 levels deep");
    /* the top-level object is level 1, "extras" starts level 2 */
    std::string over = ",\"extras\":" + std::string(128, '[') + std::string(128, ']');
    write_file("over.gltf", gltf("{\"mesh\":0}", "0", triangle_uri(), over));
    expect_refused("over.gltf", "more than 128 levels deep");
    std::string at = ",\"extras\":" + std::string(100, '[') + std::string(100, ']');
    write_file("at.gltf", gltf("{\"mesh\":0}", "0", triangle_uri(), at));
    assert_int_equal(load_in_child("at.gltf").status, 0);
    /* brackets inside strings do not count */
    std::string str = ",\"extras\":\"" + std::string(1000, '[') + "\"";
    write_file("str.gltf", gltf("{\"mesh\":0}", "0", triangle_uri(), str));
    assert_int_equal(load_in_child("str.gltf").status, 0);
}

/* A FIFO or a symlink to /dev/zero, as the scene and as a buffer's uri. */
void special_files(void **) {
    assert_int_equal(mkfifo((dir + "/fifo.gltf").c_str(), 0600), 0);
    expect_refused("fifo.gltf", "not a regular file");
    assert_int_equal(symlink("/dev/zero", (dir + "/zero.gltf").c_str()), 0);
    expect_refused("zero.gltf", "not a regular file");
    assert_int_equal(mkfifo((dir + "/fifo.bin").c_str(), 0600), 0);
    write_file("fifo_buffer.gltf", gltf("{\"mesh\":0}", "0", "fifo.bin"));
    expect_refused("fifo_buffer.gltf", "not a regular file");
    assert_int_equal(symlink("/dev/zero", (dir + "/zero.bin").c_str()), 0);
    write_file("zero_buffer.gltf", gltf("{\"mesh\":0}", "0", "zero.bin"));
    expect_refused("zero_buffer.gltf", "not a regular file");
    expect_refused("directory.gltf/..", "not a regular file");
}

/* A buffer declaring 1 KB whose .bin is 64 MB (sparse: no disk): refused from the file's size
   without reading it, so the peak memory stays far below 64 MB. The exact size loads. */
void oversized_buffer(void **) {
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::string tri(reinterpret_cast<const char *>(p), sizeof p);
    for (const char *name : {"big.bin", "exact.bin"}) {
        write_file(name, tri);
        int fd = open((dir + "/" + name).c_str(), O_WRONLY);
        assert_true(fd >= 0);
        assert_int_equal(ftruncate(fd, std::strcmp(name, "big.bin") == 0 ? 64L << 20 : 1024), 0);
        close(fd);
    }
    std::string declare = "\"buffers\":[{\"byteLength\":36,";
    std::string big = gltf("{\"mesh\":0}", "0", "big.bin");
    big.replace(big.find(declare), declare.size(), "\"buffers\":[{\"byteLength\":1024,");
    write_file("big_buffer.gltf", big);
    outcome o = load_in_child("big_buffer.gltf");
    assert_true(o.status > 0);
    assert_true(o.seconds < 5 && o.peak_kb < 48 * 1024);
    if (!std::strstr(o.err.c_str(), "more than the 1024 its buffer declares")) fail_msg("got '%s'", o.err.c_str());
    std::string exact = gltf("{\"mesh\":0}", "0", "exact.bin");
    exact.replace(exact.find(declare), declare.size(), "\"buffers\":[{\"byteLength\":1024,");
    write_file("exact_buffer.gltf", exact);
    assert_int_equal(load_in_child("exact_buffer.gltf").status, 0);
    /* a file shorter than declared is refused by tinygltf's size check, as before */
    std::string shorter = gltf("{\"mesh\":0}", "0", "exact.bin");
    shorter.replace(shorter.find(declare), declare.size(), "\"buffers\":[{\"byteLength\":2048,");
    write_file("short_buffer.gltf", shorter);
    expect_refused("short_buffer.gltf", "File size mismatch");
}

void put32(std::string &s, uint32_t v) {
    for (int k = 3; k >= 0; --k) s += (char)((v >> (8 * k)) & 0xff);
}
void chunk(std::string &png, const char *type, const std::string &data) {
    put32(png, (uint32_t)data.size());
    std::string td = std::string(type, 4) + data;
    png += td;
    put32(png, (uint32_t)crc32(0, reinterpret_cast<const Bytef *>(td.data()), (uInt)td.size()));
}

/* A 1-bit grey PNG of side x side, all zero: a few tens of KB that decode to side^2 RGBA. */
std::string bomb_png(uint32_t side) {
    std::string raw((size_t)side * (1 + side / 8), '\0');
    uLongf zn = compressBound((uLong)raw.size());
    std::vector<Bytef> z(zn);
    assert_int_equal(compress2(z.data(), &zn, reinterpret_cast<const Bytef *>(raw.data()), (uLong)raw.size(), 9), Z_OK);
    std::string png("\x89PNG\r\n\x1a\n", 8), ihdr;
    put32(ihdr, side);
    put32(ihdr, side);
    ihdr += std::string("\x01\x00\x00\x00\x00", 5); /* depth 1, grey, deflate, filter 0, no interlace */
    chunk(png, "IHDR", ihdr);
    chunk(png, "IDAT", std::string(reinterpret_cast<const char *>(z.data()), zn));
    chunk(png, "IEND", "");
    return png;
}

/* A 16384^2 PNG used by 8 images (each a base colour texture): the file loads, the images
   are skipped with a warning, and the peak memory stays far below the 8 GiB they decode to. */
void decompression_bomb(void **) {
    std::string png = bomb_png(16384);
    std::printf("  bomb.png: %zu bytes\n", png.size());
    write_file("bomb.png", png);
    std::string images, textures, materials;
    for (int i = 0; i < 8; ++i) {
        images += std::string(i ? "," : "") + "{\"uri\":\"bomb.png\"}";
        textures += std::string(i ? "," : "") + "{\"source\":" + std::to_string(i) + "}";
        materials += std::string(i ? "," : "") + "{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":" +
                     std::to_string(i) + "}}}";
    }
    write_file("bomb.gltf", gltf("{\"mesh\":0}", "0", triangle_uri(),
                                 ",\"images\":[" + images + "],\"textures\":[" + textures + "],\"materials\":[" + materials + "]"));
    outcome o = load_in_child("bomb.gltf");
    assert_int_equal(o.status, 0);
    assert_true(o.seconds < LIMIT_S && o.peak_kb < LIMIT_KB);
    assert_non_null(std::strstr(o.err.c_str(), "skipped"));
}

/* Each node lists its child twice, 18 deep: 2^18 = 262,144 instances of the triangle from a
   file of 3 KB; refused from the declared counts before anything is expanded. 2^15 loads. */
void instancing_explosion(void **) {
    for (int depth : {18, 15}) {
        std::string nodes;
        for (int i = 0; i < depth; ++i)
            nodes += "{\"children\":[" + std::to_string(i + 1) + "," + std::to_string(i + 1) + "]},";
        nodes += "{\"mesh\":0}";
        std::string name = "graph" + std::to_string(depth) + ".gltf";
        write_file(name, gltf(nodes, "0", triangle_uri()));
        if (depth == 18) expect_refused(name, "expands to 262144 mesh instances");
        else assert_int_equal(load_in_child(name).status, 0);
    }
}

} /* namespace */

int main(void) {
    char tmpl[] = "/tmp/gimany-loader-XXXXXX";
    assert_non_null(mkdtemp(tmpl));
    dir = tmpl;
    assert_int_equal(mkdir((dir + "/directory.gltf").c_str(), 0700), 0);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ordinary_file_loads), cmocka_unit_test(deep_nesting),      cmocka_unit_test(special_files),
        cmocka_unit_test(oversized_buffer),    cmocka_unit_test(decompression_bomb),
        cmocka_unit_test(instancing_explosion),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    std::string rm = "rm -rf '" + dir + "'";
    if (std::system(rm.c_str()) != 0) std::fprintf(stderr, "could not remove %s\n", dir.c_str());
    return r;
}
