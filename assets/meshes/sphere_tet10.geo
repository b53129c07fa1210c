// Regenerate: gmsh -3 assets/meshes/sphere_tet10.geo -o assets/meshes/sphere_tet10.msh (gmsh 4.8, Debian 12).
// Used by the render golden tests (tests/render): 261 tet10, radius 1.
// Unit-radius sphere, order-2 tets (mid-edge nodes on the sphere).
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 1.0};
Mesh.CharacteristicLengthMin = 0.5;
Mesh.CharacteristicLengthMax = 0.5;
Mesh.ElementOrder = 2;
Mesh.SecondOrderLinear = 0;
Mesh.MshFileVersion = 4.1;
