#version 330 core
// A triangle that covers the screen; the raycast image is its texture.
out vec2 uv;
void main() {
  vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
  uv = vec2(p.x, 1.0 - p.y);  // the image's row 0 is the top
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
