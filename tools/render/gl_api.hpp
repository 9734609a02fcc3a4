// tools/render/gl_api.hpp — the OpenGL 3.3 core functions the renderer calls, loaded at run
// time through the context's own lookup (OSMesaGetProcAddress for `weft render`,
// glfwGetProcAddress for `weft view`).
//
// Design note
// -----------
// The renderer never calls a gl* symbol by name: every function is a pointer in a GlApi,
// filled from the current context. So the `weft` binary links no GL library at all (OSMesa
// is opened with dlopen, GLFW opens libGL itself), the two contexts' libraries never
// interpose each other's symbols, and a missing function is reported by name when the
// context is made, not as a crash mid-frame.
#pragma once

#include <GL/glcorearb.h>

#include <string>

namespace weftrender {

// X(type, name) for every GL function the renderer uses (OpenGL 3.3 core).
#define WEFT_GL_FUNCTIONS(X)                                   \
  X(PFNGLGETSTRINGPROC, GetString)                             \
  X(PFNGLGETERRORPROC, GetError)                               \
  X(PFNGLVIEWPORTPROC, Viewport)                               \
  X(PFNGLSCISSORPROC, Scissor)                                 \
  X(PFNGLCLEARCOLORPROC, ClearColor)                           \
  X(PFNGLCLEARPROC, Clear)                                     \
  X(PFNGLENABLEPROC, Enable)                                   \
  X(PFNGLDISABLEPROC, Disable)                                 \
  X(PFNGLDEPTHFUNCPROC, DepthFunc)                             \
  X(PFNGLDEPTHMASKPROC, DepthMask)                             \
  X(PFNGLBLENDFUNCPROC, BlendFunc)                             \
  X(PFNGLPOLYGONOFFSETPROC, PolygonOffset)                     \
  X(PFNGLSTENCILFUNCPROC, StencilFunc)                         \
  X(PFNGLSTENCILOPPROC, StencilOp)                             \
  X(PFNGLCLEARSTENCILPROC, ClearStencil)                       \
  X(PFNGLFINISHPROC, Finish)                                   \
  X(PFNGLPIXELSTOREIPROC, PixelStorei)                         \
  X(PFNGLREADPIXELSPROC, ReadPixels)                           \
  X(PFNGLREADBUFFERPROC, ReadBuffer)                           \
  X(PFNGLCREATESHADERPROC, CreateShader)                       \
  X(PFNGLSHADERSOURCEPROC, ShaderSource)                       \
  X(PFNGLCOMPILESHADERPROC, CompileShader)                     \
  X(PFNGLGETSHADERIVPROC, GetShaderiv)                         \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)               \
  X(PFNGLDELETESHADERPROC, DeleteShader)                       \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram)                     \
  X(PFNGLATTACHSHADERPROC, AttachShader)                       \
  X(PFNGLBINDATTRIBLOCATIONPROC, BindAttribLocation)           \
  X(PFNGLLINKPROGRAMPROC, LinkProgram)                         \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                       \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)             \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                     \
  X(PFNGLUSEPROGRAMPROC, UseProgram)                           \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)           \
  X(PFNGLUNIFORMMATRIX4FVPROC, UniformMatrix4fv)               \
  X(PFNGLUNIFORM3FVPROC, Uniform3fv)                           \
  X(PFNGLUNIFORM4FVPROC, Uniform4fv)                           \
  X(PFNGLUNIFORM1FPROC, Uniform1f)                             \
  X(PFNGLGENVERTEXARRAYSPROC, GenVertexArrays)                 \
  X(PFNGLBINDVERTEXARRAYPROC, BindVertexArray)                 \
  X(PFNGLDELETEVERTEXARRAYSPROC, DeleteVertexArrays)           \
  X(PFNGLGENBUFFERSPROC, GenBuffers)                           \
  X(PFNGLBINDBUFFERPROC, BindBuffer)                           \
  X(PFNGLBUFFERDATAPROC, BufferData)                           \
  X(PFNGLDELETEBUFFERSPROC, DeleteBuffers)                     \
  X(PFNGLENABLEVERTEXATTRIBARRAYPROC, EnableVertexAttribArray) \
  X(PFNGLVERTEXATTRIBPOINTERPROC, VertexAttribPointer)         \
  X(PFNGLDRAWELEMENTSPROC, DrawElements)                       \
  X(PFNGLDRAWARRAYSPROC, DrawArrays)

/// The loaded functions: GlApi::Viewport(...) is glViewport(...).
struct GlApi {
#define WEFT_GL_DECLARE(type, name) type name = nullptr;
  WEFT_GL_FUNCTIONS(WEFT_GL_DECLARE)
#undef WEFT_GL_DECLARE
};

/// A context's function lookup (OSMesaGetProcAddress, glfwGetProcAddress, ...).
using GlLookup = void* (*)(const char* name);

/// Fills every function through `lookup` (with a context current). Throws
/// std::runtime_error naming the first function the context does not provide.
GlApi loadGl(GlLookup lookup);

}  // namespace weftrender
