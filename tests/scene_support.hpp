#pragma once
// Helpers for tests that run scenes (they link the scene module).

#include "incise/scene/scene.hpp"

namespace incise::test {

/// The default scene (the seed's Fig. 10 block cut by a scalpel), shortened to `frames`.
inline SceneDescription short_default(int frames) {
  SceneDescription scene = default_scene();
  scene.frames = frames;
  return scene;
}

}  // namespace incise::test
