#include "window.hpp"

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include "incise/core/error.hpp"

namespace incise::app {

namespace {

std::string glfw_error;  // the last GLFW error, for the message when a window cannot be had

}  // namespace

GLFWwindow* open_window(int width, int height, const std::string& title, int swap_interval,
                        void* user) {
  glfwSetErrorCallback([](int, const char* description) { glfw_error = description; });
  if (glfwInit() != GLFW_TRUE) {
    throw Error(
        "incise view needs a display (X11 or Wayland); without one run it under "
        "xvfb-run, or use incise run --render for pictures. GLFW: " +
        glfw_error);
  }
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
  glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
  glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
  glfwWindowHint(GLFW_SAMPLES, 0);  // llvmpipe draws 4x-multisampled windows at half the rate
  GLFWwindow* window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (window == nullptr) {
    glfwTerminate();
    throw Error("incise view cannot open an OpenGL 3.3 window: " + glfw_error);
  }
  glfwMakeContextCurrent(window);
  glfwSwapInterval(swap_interval);
  glfwSetWindowUserPointer(window, user);
  return window;
}

void start_imgui(GLFWwindow* window) {
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(window, true);
  ImGui_ImplOpenGL3_Init("#version 330 core");
}

Image read_window_picture(GLFWwindow* window) {
  int width = 0;
  int height = 0;
  glfwGetFramebufferSize(window, &width, &height);
  Image image(width, height);
  glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, image.pixels().data());
  image.flip_rows();
  for (Rgba& pixel : image.pixels()) {
    pixel.a = 255;
  }
  return image;
}

void close_window(GLFWwindow* window) {
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
  glfwDestroyWindow(window);
  glfwTerminate();
}

}  // namespace incise::app
