#version 430
// Depth-only pass: the depth attachment is all that is written.
void main() {
}
