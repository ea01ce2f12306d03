#version 430
// Depth-only pass (shadow maps): the depth attachment is all that is written.
void main() {
}
