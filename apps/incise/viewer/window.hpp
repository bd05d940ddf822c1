#pragma once
// The viewers' window: GLFW with an OpenGL 3.3 core context and Dear ImGui on it. Shared by
// the cutting viewer (viewer.hpp) and the planning viewer (plan_viewer.hpp).

#include <string>

#include "incise/render/image.hpp"

struct GLFWwindow;

namespace incise::app {

/// Opens a window (initialising GLFW first) with `swap_interval` (0: no vsync); throws
/// incise::Error with GLFW's reason when there is no display or no context. `user` becomes the
/// window's user pointer (its callbacks find their viewer through it).
GLFWwindow* open_window(int width, int height, const std::string& title, int swap_interval,
                        void* user);

/// Dear ImGui on the window: after the window's own input callbacks are installed (ImGui's
/// chain to them). No imgui.ini is left in the user's folder.
void start_imgui(GLFWwindow* window);

/// What the window's back buffer holds now (drawn, not yet swapped), rows from the top, opaque.
[[nodiscard]] Image read_window_picture(GLFWwindow* window);

/// Closes what open_window opened (ImGui, the window, GLFW).
void close_window(GLFWwindow* window);

}  // namespace incise::app
