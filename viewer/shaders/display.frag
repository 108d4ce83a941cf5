#version 330 core
// The raycast image as the raycaster encoded it (8-bit, gamma applied).
in vec2 uv;
out vec4 colour;
uniform sampler2D image;
void main() { colour = vec4(texture(image, uv).rgb, 1.0); }
