/* An OpenGL 4.5 host written in C (no Rust in it): it walks the Fox with its own poses (the clip
 * sampler's), steps it through furbake's C interface and draws its skin, shells and fins with the
 * GLSL that `furbake shaders --target glsl` exported, on a headless EGL context (Mesa's llvmpipe on
 * a machine without a GPU), then writes the frame as raw RGBA8 rows, top row first.
 *
 * Usage: gl_fur FOX.fbk SHADER_DIR OUT.rgba WIDTH HEIGHT STEPS LOOK THRESHOLD NAME=BINDING...
 * LOOK is `default` — furbake's own look: every shell the level of detail gives for this view,
 * blended with the stacking exponents, strand-shaded, the atlas's mip chain sampled, then the fins
 * and the silhouette fins this view selects (`default_without_fins` leaves the fins out) — or
 * `alpha_test`: every shell, alpha-tested at THRESHOLD, Lambert × self-shadow. Each NAME=BINDING
 * gives the GLSL binding manifest.json assigns the resource NAME (frame, fur, scale_vectors,
 * shadow, shell_alpha, stacking; for the fins fin_alpha, sil_edges, sil_instances, sil_vertices,
 * sil_colors, and the selection's params, edges, vertices, instances, args). The camera and light are the ones the crate's test gives
 * furbake's renderer (keep them in step with tests/gl_host.rs). */

#define GL_GLEXT_PROTOTYPES 1
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/glcorearb.h>

#include "furbake.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MUST(call)                                                                                 \
    do {                                                                                           \
        FurbakeResult r_ = (call);                                                                 \
        if (r_ != FURBAKE_RESULT_OK) {                                                             \
            fprintf(stderr, "gl_fur.c:%d: %s failed (%d): %s\n", __LINE__, #call, (int)r_,        \
                    furbake_last_error());                                                         \
            exit(1);                                                                               \
        }                                                                                          \
    } while (0)

static void die(const char *what) {
    fprintf(stderr, "gl_fur.c: %s\n", what);
    exit(1);
}

static char *read_text(const char *dir, const char *name) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        exit(1);
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *text = malloc((size_t)n + 1);
    if (!text || fread(text, 1, (size_t)n, f) != (size_t)n) {
        die("cannot read a shader");
    }
    text[n] = 0;
    fclose(f);
    return text;
}

static GLuint compile(GLenum stage, const char *dir, const char *name) {
    char *source = read_text(dir, name);
    GLuint shader = glCreateShader(stage);
    const char *sources[] = {source};
    glShaderSource(shader, 1, sources, NULL);
    glCompileShader(shader);
    GLint ok = 0;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[4096];
        glGetShaderInfoLog(shader, sizeof log, NULL, log);
        fprintf(stderr, "%s: %s\n", name, log);
        exit(1);
    }
    free(source);
    return shader;
}

/* Column-major 4×4 matrices, as glam (and WGSL) store them. */
typedef struct {
    float m[16];
} Mat4;

static Mat4 mul(Mat4 a, Mat4 b) {
    Mat4 r;
    for (int c = 0; c < 4; c++) {
        for (int row = 0; row < 4; row++) {
            float s = 0.0f;
            for (int k = 0; k < 4; k++) {
                s += a.m[k * 4 + row] * b.m[c * 4 + k];
            }
            r.m[c * 4 + row] = s;
        }
    }
    return r;
}

static void normalize3(float v[3]) {
    float l = sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    v[0] /= l;
    v[1] /= l;
    v[2] /= l;
}

static void cross3(const float a[3], const float b[3], float out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Right-handed look-at and a perspective with depth in [0, 1] (what glam's look_at_rh and
 * perspective_rh compute). */
static Mat4 look_at(const float eye[3], const float target[3], const float up[3]) {
    float f[3] = {target[0] - eye[0], target[1] - eye[1], target[2] - eye[2]};
    normalize3(f);
    float s[3], u[3];
    cross3(f, up, s);
    normalize3(s);
    cross3(s, f, u);
    Mat4 m = {{s[0], u[0], -f[0], 0, s[1], u[1], -f[1], 0, s[2], u[2], -f[2], 0,
               -(s[0] * eye[0] + s[1] * eye[1] + s[2] * eye[2]), -(u[0] * eye[0] + u[1] * eye[1] + u[2] * eye[2]),
               f[0] * eye[0] + f[1] * eye[1] + f[2] * eye[2], 1}};
    return m;
}

static Mat4 perspective(float fov_y, float aspect, float near, float far) {
    float h = 1.0f / tanf(0.5f * fov_y), w = h / aspect, r = far / (near - far);
    Mat4 m = {{w, 0, 0, 0, 0, h, 0, 0, 0, 0, r, -1, 0, 0, r * near, 0}};
    return m;
}

/* One vertex per triangle corner (furbake_pack_surface_vertices; vs_skin's and vs_shell's
 * inputs). */
typedef struct {
    float position[3];
    float normal[3];
    float color[4];
    float uv[2];
    uint32_t vertex_index, flags, corner_index;
} Corner;

static GLuint binding_of(int argc, char **argv, const char *name) {
    size_t n = strlen(name);
    for (int i = 9; i < argc; i++) {
        if (strncmp(argv[i], name, n) == 0 && argv[i][n] == '=') {
            return (GLuint)atoi(argv[i] + n + 1);
        }
    }
    fprintf(stderr, "gl_fur.c: no binding given for %s\n", name);
    exit(2);
}

/* Links `program`, or stops with the driver's log naming `what`. */
static void link_program(GLuint program, const char *what) {
    glLinkProgram(program);
    GLint linked = 0;
    glGetProgramiv(program, GL_LINK_STATUS, &linked);
    if (!linked) {
        char log[4096];
        glGetProgramInfoLog(program, sizeof log, NULL, log);
        fprintf(stderr, "link %s: %s\n", what, log);
        exit(1);
    }
}

static GLuint program_of(const char *dir, const char *vertex, const char *fragment) {
    GLuint program = glCreateProgram();
    glAttachShader(program, compile(GL_VERTEX_SHADER, dir, vertex));
    glAttachShader(program, compile(GL_FRAGMENT_SHADER, dir, fragment));
    link_program(program, vertex);
    glUseProgram(program);
    GLint first_instance = glGetUniformLocation(program, "naga_vs_first_instance");
    if (first_instance >= 0) {
        glUniform1ui(first_instance, 0);
    }
    return program;
}

static GLuint compute_program_of(const char *dir, const char *name) {
    GLuint program = glCreateProgram();
    glAttachShader(program, compile(GL_COMPUTE_SHADER, dir, name));
    link_program(program, name);
    return program;
}

static GLuint storage_buffer(const void *data, size_t bytes) {
    GLuint buffer;
    glGenBuffers(1, &buffer);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)(bytes > 0 ? bytes : 16), data, GL_DYNAMIC_DRAW);
    return buffer;
}

/* An R8 2D texture (array) of `atlas` with every mip level furbake makes, on texture unit `unit`,
 * filtered anisotropically up to `anisotropy` (the look's, for blended fur; 1 for the alpha test,
 * which reads level 0). */
static GLuint atlas_texture(const FurbakePack *pack, uint32_t atlas, GLuint unit, float anisotropy) {
    GLenum kind = atlas == FURBAKE_ATLAS_SHELL ? GL_TEXTURE_2D_ARRAY : GL_TEXTURE_2D;
    GLuint texture;
    glGenTextures(1, &texture);
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(kind, texture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    FurbakeAtlasLevelView mip = {.size = sizeof mip};
    MUST(furbake_pack_atlas_level(pack, atlas, 0, &mip));
    for (uint32_t l = 0; l < mip.level_count; l++) {
        MUST(furbake_pack_atlas_level(pack, atlas, l, &mip));
        if (kind == GL_TEXTURE_2D_ARRAY) {
            glTexImage3D(kind, (GLint)l, GL_R8, (GLsizei)mip.width, (GLsizei)mip.height, (GLsizei)mip.layers, 0, GL_RED,
                         GL_UNSIGNED_BYTE, mip.texels);
        } else {
            glTexImage2D(kind, (GLint)l, GL_R8, (GLsizei)mip.width, (GLsizei)mip.height, 0, GL_RED, GL_UNSIGNED_BYTE,
                         mip.texels);
        }
    }
    /* Trilinear; repeating, except the fin atlas clamps along the hair (v). */
    glTexParameteri(kind, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTexParameteri(kind, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(kind, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(kind, GL_TEXTURE_WRAP_T, atlas == FURBAKE_ATLAS_SHELL ? GL_REPEAT : GL_CLAMP_TO_EDGE);
    glTexParameteri(kind, GL_TEXTURE_MAX_LEVEL, (GLint)mip.level_count - 1);
    glTexParameterf(kind, GL_TEXTURE_MAX_ANISOTROPY, anisotropy);
    return texture;
}

/* The inverse of a rotation × uniform scale + translation matrix, applied to a point. */
static void to_object(const Mat4 *model, const float p[3], float out[3]) {
    const float *m = model->m;
    float s2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
    float d[3] = {p[0] - m[12], p[1] - m[13], p[2] - m[14]};
    for (int i = 0; i < 3; i++) { /* R^T d / s^2: the columns' dot products */
        out[i] = (m[4 * i] * d[0] + m[4 * i + 1] * d[1] + m[4 * i + 2] * d[2]) / s2;
    }
}

/* The fins, as furbake draws them after the shells: the fin quads of the pack's fin edges, then
 * the silhouette fins — this frame's interior edges on or near the silhouette, selected by the
 * exported compute pass (`silhouette.cs_silhouette`) into an instance list and an indirect draw's
 * arguments, then drawn six vertices per instance. Blended, depth tested but not written. The
 * storage bindings of the fin and selection programs overlap the shells' (the manifest numbers
 * each module on its own), so each is bound just before its program runs. */
static void draw_fins(int argc, char **argv, const char *dir, const FurbakePack *fox, const FurbakeSkinPose *pose,
                      const FurbakeSkinMeshView *mesh, const Mat4 *model, const float eye[3], GLuint frame,
                      GLuint scale_vectors, GLuint shadow, float anisotropy) {
    FurbakeArrayView quads = {.size = sizeof quads}, edges = {.size = sizeof edges};
    MUST(furbake_pack_fin_quads(fox, &quads));
    MUST(furbake_pack_silhouette_edges(fox, &edges));
    GLuint fin_texture = atlas_texture(fox, FURBAKE_ATLAS_FIN, binding_of(argc, argv, "fin_alpha"), anisotropy);
    GLuint fins = program_of(dir, "fin.vs_fin.shear-strand.vert", "fin.fs_fin.alpha_blend-lambert-shadow-strand.light_slots1.frag");
    GLuint silhouette_fins = program_of(dir, "fin.vs_silhouette_fin.shear-strand.vert",
                                        "fin.fs_fin.alpha_blend-lambert-shadow-strand.light_slots1.frag");
    GLuint select = compute_program_of(dir, "silhouette.cs_silhouette.comp");

    if (quads.count > 0) { /* the Fox has none: every furry edge is interior */
        GLuint vao, vbo;
        glGenVertexArrays(1, &vao);
        glBindVertexArray(vao);
        glGenBuffers(1, &vbo);
        glBindBuffer(GL_ARRAY_BUFFER, vbo);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)quads.count * quads.stride, quads.data, GL_STATIC_DRAW);
        const GLsizei stride = (GLsizei)quads.stride;
        const GLint sizes[9] = {3, 3, 3, 4, 1, 1, 1, 1, 3};
        const size_t offsets[9] = {0, 12, 24, 36, 52, 56, 60, 64, 68};
        for (GLuint a = 0; a < 9; a++) {
            glEnableVertexAttribArray(a);
            if (a < 6) {
                glVertexAttribPointer(a, sizes[a], GL_FLOAT, GL_FALSE, stride, (void *)offsets[a]);
            } else {
                glVertexAttribIPointer(a, sizes[a], GL_UNSIGNED_INT, stride, (void *)offsets[a]);
            }
        }
        glUseProgram(fins);
        glDrawArrays(GL_TRIANGLES, 0, (GLsizei)quads.count);
    }

    /* The selection's inputs: this frame's posed vertices (position, normal as vec4s), the eye
     * in the pack's frame, the band of furbake's default (0.05). */
    float *posed = calloc(8 * (size_t)pose->vertex_count, sizeof(float));
    for (uint32_t v = 0; v < pose->vertex_count; v++) {
        memcpy(&posed[8 * v], &pose->positions[3 * v], 3 * sizeof(float));
        posed[8 * v + 3] = 1.0f;
        memcpy(&posed[8 * v + 4], &pose->normals[3 * v], 3 * sizeof(float));
    }
    GLuint vertices = storage_buffer(posed, 32 * (size_t)pose->vertex_count);
    free(posed);
    GLuint edge_buffer = storage_buffer(edges.data, (size_t)edges.count * edges.stride);
    GLuint colors = storage_buffer(mesh->colors, 16 * (size_t)mesh->vertex_count);
    GLuint instances = storage_buffer(NULL, 8 * (size_t)edges.count);
    const uint32_t args[4] = {6, 0, 0, 0}; /* six vertices per fin; the selection counts instances */
    GLuint arguments = storage_buffer(args, sizeof args);
    float params[8] = {0};
    to_object(model, eye, params);
    params[3] = 1.0f;
    params[4] = 0.05f;
    memcpy(&params[5], &edges.count, 4);
    GLuint params_buffer;
    glGenBuffers(1, &params_buffer);
    glBindBuffer(GL_UNIFORM_BUFFER, params_buffer);
    glBufferData(GL_UNIFORM_BUFFER, sizeof params, params, GL_STATIC_DRAW);

    glUseProgram(select);
    glBindBufferBase(GL_UNIFORM_BUFFER, binding_of(argc, argv, "params"), params_buffer);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "edges"), edge_buffer);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "vertices"), vertices);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "instances"), instances);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "args"), arguments);
    glDispatchCompute((edges.count + 63) / 64, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
    /* The selection took bindings the fins read too (its parameters on the frame's uniform
     * binding, its buffers on the storage bindings of the scale vectors and shadow table). */
    glBindBufferBase(GL_UNIFORM_BUFFER, binding_of(argc, argv, "frame"), frame);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "scale_vectors"), scale_vectors);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "shadow"), shadow);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "sil_edges"), edge_buffer);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "sil_instances"), instances);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "sil_vertices"), vertices);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "sil_colors"), colors);
    glUseProgram(silhouette_fins);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, arguments);
    glDrawArraysIndirect(GL_TRIANGLES, NULL);
    uint32_t drawn[4] = {0};
    glGetNamedBufferSubData(arguments, 0, sizeof drawn, drawn);
    printf("fins: %u fin quad corners, %u interior edges, silhouette draw of %u instances\n", quads.count,
           edges.count, drawn[1]);
    glDeleteTextures(1, &fin_texture);
}

int main(int argc, char **argv) {
    if (argc < 10) {
        fprintf(stderr, "usage: %s FOX.fbk SHADER_DIR OUT.rgba WIDTH HEIGHT STEPS LOOK THRESHOLD NAME=BINDING...\n", argv[0]);
        return 2;
    }
    const char *shader_dir = argv[2];
    const int width = atoi(argv[4]), height = atoi(argv[5]), steps = atoi(argv[6]);
    /* `default_without_fins` is furbake's look with the fins left out: the test's proof that its
     * comparison sees them. */
    const int without_fins = strcmp(argv[7], "default_without_fins") == 0;
    const int furbake_look = without_fins || strcmp(argv[7], "default") == 0;
    if (!furbake_look && strcmp(argv[7], "alpha_test") != 0) {
        die("LOOK is default, default_without_fins or alpha_test");
    }
    if (furbake_check_version(FURBAKE_ABI_VERSION) != FURBAKE_RESULT_OK) {
        die(furbake_last_error());
    }

    /* The walking Fox, stepped to the frame and posed by this program, as a game's animation
     * system would: the Walk clip sampled at each step's end time (furbake_animator_pose), the
     * joint matrices handed to the world before the step. The entry starts on the clip's first
     * pose (held: speed 0), as the scene's walking Fox does. */
    FurbakePack *fox = NULL;
    MUST(furbake_pack_open_file(argv[1], &fox));
    FurbakeWorldDesc desc = {.size = sizeof desc};
    desc.time_step_s = 0.02f;
    desc.settings_toml = "[effects.gravity]\n";
    FurbakeWorld *world = NULL;
    MUST(furbake_world_create(&desc, &world));
    FurbakeEntryDesc entry = {.size = sizeof entry};
    entry.name = "fox";
    entry.animation = FURBAKE_ANIMATION_CLIP;
    entry.clip = "Walk";
    entry.speed = 0.0f;
    entry.looping = 1;
    entry.scale = 0.01f;
    MUST(furbake_world_add_pack(world, fox, &entry, NULL));
    FurbakeAnimator *walk = NULL;
    MUST(furbake_animator_create(fox, "Walk", &walk));
    for (int k = 1; k <= steps; k++) {
        FurbakeSkinPose sampled = {.size = sizeof sampled};
        MUST(furbake_animator_pose(walk, k * 0.02, &sampled));
        MUST(furbake_world_set_joint_matrices(world, 0, sampled.joint_matrices, sampled.joint_count,
                                              sampled.morph_weights, sampled.morph_count));
        MUST(furbake_world_step(world));
    }
    furbake_animator_release(walk);
    FurbakeSkinMeshView mesh = {.size = sizeof mesh};
    MUST(furbake_pack_skin_mesh(fox, &mesh));
    FurbakeShellAtlasView atlas = {.size = sizeof atlas};
    MUST(furbake_pack_shell_atlas(fox, &atlas));
    FurbakeSkinPose pose = {.size = sizeof pose};
    MUST(furbake_world_skin_pose(world, 0, &pose));
    Mat4 model;
    MUST(furbake_world_model_matrix(world, 0, model.m));
    FurbakeTriangleUvMapView uv_map = {.size = sizeof uv_map};
    MUST(furbake_pack_triangle_uv_map(fox, &uv_map));
    FurbakeFurFrame fur_frame = {.size = sizeof fur_frame};
    MUST(furbake_world_fur_frame(world, 0, &fur_frame));
    if (fur_frame.layout != 0) {
        die("this host draws fur with one scale vector per skin vertex");
    }

    /* A headless OpenGL 4.5 core context. */
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_display) {
        die("no eglGetPlatformDisplayEXT");
    }
    EGLDisplay display = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor) || !eglBindAPI(EGL_OPENGL_API)) {
        die("EGL does not initialise");
    }
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 5,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                         EGL_NONE};
    EGLContext context = eglCreateContext(display, EGL_NO_CONFIG_KHR, EGL_NO_CONTEXT, context_attributes);
    if (context == EGL_NO_CONTEXT || !eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context)) {
        die("no OpenGL 4.5 core context");
    }
    fprintf(stderr, "gl_fur: %s, %s\n", (const char *)glGetString(GL_RENDERER), (const char *)glGetString(GL_VERSION));

    /* The exported programs: the skin and the shells as furbake draws them for this scene —
     * bind pose from the vertex attributes (the posed skin comes from the C interface), one
     * light; the shells sheared by the scale vectors. furbake's look: strand shading on skin and
     * shells, shells blended; the alpha-test look: Lambert × self-shadow, shells alpha-tested. */
    GLuint skin = program_of(shader_dir, "skin.vs_skin.none.vert",
                             furbake_look ? "skin.fs_skin.lambert-shadow-strand.light_slots1.frag"
                                          : "skin.fs_skin.lambert-shadow.light_slots1.frag");
    GLuint shells = furbake_look
                        ? program_of(shader_dir, "shell.vs_shell.shear-strand.vert",
                                     "shell.fs_shell.alpha_blend-lambert-shadow-strand.light_slots1.frag")
                        : program_of(shader_dir, "shell.vs_shell.shear.vert",
                                     "shell.fs_shell.lambert-shadow.light_slots1.frag");

    /* Vertices: the pack's triangle corners, furry triangles first (the shells draw that
     * prefix), moved to this frame's pose. */
    FurbakeSurfaceView surface = {.size = sizeof surface};
    MUST(furbake_pack_surface_vertices(fox, &surface));
    if (surface.stride != sizeof(Corner)) {
        die("the surface vertices are not laid out as this host's Corner");
    }
    size_t corners = surface.vertex_count, furry_corners = surface.furry_vertex_count;
    Corner *vertices = malloc(corners * sizeof(Corner));
    memcpy(vertices, surface.vertices, corners * sizeof(Corner));
    for (size_t i = 0; i < corners; i++) {
        uint32_t v = vertices[i].vertex_index, corner = vertices[i].corner_index;
        if (v >= mesh.vertex_count || corner >= 3 * mesh.triangle_count ||
            memcmp(vertices[i].uv, &uv_map.corners[2 * corner], sizeof vertices[i].uv) != 0 ||
            (i < furry_corners) != (mesh.fur_mask[corner / 3] != 0)) {
            die("a surface vertex disagrees with the skin mesh and triangle UV map");
        }
        memcpy(vertices[i].position, &pose.positions[3 * v], sizeof vertices[i].position);
        memcpy(vertices[i].normal, &pose.normals[3 * v], sizeof vertices[i].normal);
    }
    GLuint vao, vbo;
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glGenBuffers(1, &vbo);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(corners * sizeof(Corner)), vertices, GL_STATIC_DRAW);
    free(vertices);
    const GLsizei stride = sizeof(Corner);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, stride, (void *)offsetof(Corner, position));
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, stride, (void *)offsetof(Corner, normal));
    glEnableVertexAttribArray(2);
    glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, stride, (void *)offsetof(Corner, color));
    glEnableVertexAttribArray(3);
    glVertexAttribPointer(3, 2, GL_FLOAT, GL_FALSE, stride, (void *)offsetof(Corner, uv));
    glEnableVertexAttribArray(4);
    glVertexAttribIPointer(4, 1, GL_UNSIGNED_INT, stride, (void *)offsetof(Corner, vertex_index));
    glEnableVertexAttribArray(5);
    glVertexAttribIPointer(5, 1, GL_UNSIGNED_INT, stride, (void *)offsetof(Corner, flags));
    glEnableVertexAttribArray(6);
    glVertexAttribIPointer(6, 1, GL_UNSIGNED_INT, stride, (void *)offsetof(Corner, corner_index));

    /* Frame uniforms (struct Frame of manifest.json: 352 bytes). */
    const float eye[3] = {1.6f, 0.9f, 2.0f}, target[3] = {0.0f, 0.35f, 0.0f}, up[3] = {0.0f, 1.0f, 0.0f};
    float frame[88] = {0};
    Mat4 view_proj = mul(perspective(40.0f * 3.14159265358979f / 180.0f, (float)width / (float)height, 0.05f, 50.0f),
                         look_at(eye, target, up));
    memcpy(&frame[0], view_proj.m, 64);
    memcpy(&frame[16], eye, 12);
    frame[19] = 1.0f;
    const float sky[3] = {0.2f, 0.22f, 0.25f}, ground[3] = {0.1f, 0.09f, 0.08f};
    memcpy(&frame[20], sky, 12);
    memcpy(&frame[24], ground, 12);
    const uint32_t light_count = 1;
    memcpy(&frame[28], &light_count, 4);
    float to_light[3] = {-0.4f, 0.8f, 0.45f}; /* minus the light's direction */
    normalize3(to_light);
    memcpy(&frame[32], to_light, 12);
    const float radiance[3] = {1.0f * 1.2f, 0.95f * 1.2f, 0.9f * 1.2f};
    memcpy(&frame[36], radiance, 12);
    memcpy(&frame[64], model.m, 64);
    frame[80] = (float)width;
    frame[81] = (float)height;
    /* The shells this view draws: furbake's level of detail for the Fox's projected fur length
     * (its default curve), or every layer. Frame.shells = (layers, fade, continuous, 0). */
    FurbakeShellLevel level = {.size = sizeof level, .layers = atlas.layers, .fade = 1.0f,
                               .continuous = (float)atlas.layers};
    if (furbake_look) {
        FurbakeCamera camera = {.size = sizeof camera, .viewport = {(float)width, (float)height}};
        memcpy(camera.view_proj, view_proj.m, sizeof camera.view_proj);
        memcpy(camera.eye, eye, sizeof camera.eye);
        MUST(furbake_world_shell_level(world, 0, &camera, NULL, atlas.layers, &level));
    }
    const uint32_t layers = level.layers;
    frame[84] = (float)level.layers;
    frame[85] = level.fade;
    frame[86] = level.continuous;
    GLuint buffers[5];
    glGenBuffers(5, buffers);
    glBindBuffer(GL_UNIFORM_BUFFER, buffers[0]);
    glBufferData(GL_UNIFORM_BUFFER, sizeof frame, frame, GL_STATIC_DRAW);
    glBindBufferBase(GL_UNIFORM_BUFFER, binding_of(argc, argv, "frame"), buffers[0]);
    /* Fur uniforms (struct Fur, 128 bytes) for furbake's default look, or with the alpha-test
     * threshold; one scale vector per skin vertex. */
    FurbakeFurLook look = {.size = sizeof look};
    MUST(furbake_fur_look_default(&look));
    if (!furbake_look) {
        look.alpha_threshold = (float)atof(argv[8]);
        look.anisotropy = 1.0f; /* the alpha test reads level 0 isotropically, as furbake's */
    }
    unsigned char fur[128];
    MUST(furbake_pack_fur_block(fox, &look, atlas.layers, fur, sizeof fur));
    glBindBuffer(GL_UNIFORM_BUFFER, buffers[1]);
    glBufferData(GL_UNIFORM_BUFFER, sizeof fur, fur, GL_STATIC_DRAW);
    glBindBufferBase(GL_UNIFORM_BUFFER, binding_of(argc, argv, "fur"), buffers[1]);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffers[2]);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)(atlas.layers * sizeof(float)), atlas.shadow, GL_STATIC_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "shadow"), buffers[2]);
    /* This frame's scale vectors, one vec4 each (xyz; w = 0). */
    float *scale = calloc(4 * (size_t)fur_frame.count, sizeof(float));
    for (uint32_t i = 0; i < fur_frame.count; i++) {
        memcpy(&scale[4 * i], &fur_frame.scale_vectors[3 * i], 3 * sizeof(float));
    }
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffers[3]);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)(4 * fur_frame.count * sizeof(float)), scale, GL_STATIC_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "scale_vectors"), buffers[3]);
    free(scale);
    /* The shells' stacking exponents (read by the blended shells). */
    FurbakeStackingTableView stacking = {.size = sizeof stacking};
    MUST(furbake_pack_stacking_table(fox, &stacking));
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buffers[4]);
    glBufferData(GL_SHADER_STORAGE_BUFFER,
                 (GLsizeiptr)(stacking.angle_bins * stacking.mip_bins * stacking.count_bins * sizeof(float)),
                 stacking.exponents, GL_STATIC_DRAW);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding_of(argc, argv, "stacking"), buffers[4]);
    /* The shell atlas: an R8 2D array texture with furbake's mip chain. */
    GLuint shell_texture = atlas_texture(fox, FURBAKE_ATLAS_SHELL, binding_of(argc, argv, "shell_alpha"),
                                         furbake_look ? look.anisotropy : 1.0f);

    /* An sRGB colour target and a float depth target, as the headless renderer's. */
    GLuint fbo, color, depth;
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glGenRenderbuffers(1, &color);
    glBindRenderbuffer(GL_RENDERBUFFER, color);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_SRGB8_ALPHA8, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, color);
    glGenRenderbuffers(1, &depth);
    glBindRenderbuffer(GL_RENDERBUFFER, depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        die("the framebuffer is incomplete");
    }
    glViewport(0, 0, width, height);
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE); /* WGSL's depth range */
    glEnable(GL_FRAMEBUFFER_SRGB);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glEnable(GL_CULL_FACE);
    glCullFace(GL_BACK);
    glFrontFace(GL_CCW);
    glClearColor(0.06f, 0.06f, 0.07f, 1.0f);
    glClearDepth(1.0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glUseProgram(skin);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)corners);
    /* Shells, blended over what is drawn (straight alpha, depth tested but not written): first
     * their back faces (front faces culled) as instances layers … 2·layers − 1, outermost first,
     * then their front faces (back faces culled) as instances 0 … layers − 1, innermost first.
     * GLSL's instance index leaves out the first instance; naga's naga_vs_first_instance uniform
     * carries it. Alpha-tested shells write depth: one draw of every face, innermost first. */
    glUseProgram(shells);
    if (furbake_look) {
        glEnable(GL_BLEND);
        glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
        glDepthMask(GL_FALSE);
        GLint first_instance = glGetUniformLocation(shells, "naga_vs_first_instance");
        glCullFace(GL_FRONT);
        glUniform1ui(first_instance, layers);
        glDrawArraysInstanced(GL_TRIANGLES, 0, (GLsizei)furry_corners, (GLsizei)layers);
        glCullFace(GL_BACK);
        glUniform1ui(first_instance, 0);
        glDrawArraysInstanced(GL_TRIANGLES, 0, (GLsizei)furry_corners, (GLsizei)layers);
        glDisable(GL_CULL_FACE);
    } else {
        glDisable(GL_CULL_FACE);
        glDrawArraysInstanced(GL_TRIANGLES, 0, (GLsizei)furry_corners, (GLsizei)layers);
    }
    if (furbake_look && !without_fins) {
        draw_fins(argc, argv, shader_dir, fox, &pose, &mesh, &model, eye, buffers[0], buffers[3], buffers[2], look.anisotropy);
    }
    glDeleteTextures(1, &shell_texture);
    GLenum error = glGetError();
    if (error != GL_NO_ERROR) {
        fprintf(stderr, "OpenGL error %#x\n", error);
        return 1;
    }

    /* Read back, top row first. */
    size_t row = 4 * (size_t)width;
    unsigned char *pixels = malloc(row * (size_t)height);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, pixels);
    FILE *out = fopen(argv[3], "wb");
    if (!out) {
        perror(argv[3]);
        return 1;
    }
    for (int y = height - 1; y >= 0; y--) {
        fwrite(pixels + (size_t)y * row, 1, row, out);
    }
    fclose(out);
    free(pixels);

    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, context);
    eglTerminate(display);
    furbake_world_release(world);
    furbake_pack_release(fox);
    printf("drew %zu corners and %u shells of %zu at %dx%d after %d steps\n", corners, layers, furry_corners, width, height, steps);
    return 0;
}
