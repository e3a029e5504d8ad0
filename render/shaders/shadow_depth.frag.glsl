#version 430
// Shadow maps: depth only (the slope-scaled offset is the pipeline's polygon offset).
void main() {}
