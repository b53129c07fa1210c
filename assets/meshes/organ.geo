// Regenerate (gmsh 4.8, Debian 12), from the repository root, one line per mesh:
//   gmsh -3 assets/meshes/organ.geo -setnumber h 0.0158 -o assets/meshes/organ_3k.msh
//   gmsh -3 assets/meshes/organ.geo -setnumber h 0.0091 -o assets/meshes/organ_10k.msh
//   gmsh -3 assets/meshes/organ.geo -setnumber h 0.0068 -o assets/meshes/organ_20k.msh
//   gmsh -3 assets/meshes/organ.geo -setnumber h 0.0058 -o assets/meshes/organ_30k.msh
// Compact organ-like blob (a liver-lobe stand-in) for the solver-policy study
// (issue 4, tools/scripts/bench-policies.sh) and the organ scenes: the union of
// three overlapping ellipsoids, cut flat at z = 0 so the bottom face can be
// clamped. About 0.12 x 0.078 x 0.05 m (x in [-0.06, 0.06], y in [-0.038, 0.04],
// z in [0, 0.05]; highest point x = -0.015, y = 0), SI units (m).
// Order-2 tets (mid-edge nodes on the curved surface). h = target edge length
// (m); the suffix is the approximate DOF count (3 x nodes). Only the
// tetrahedra are saved (Physical Volume), no surface triangles.
SetFactory("OpenCASCADE");
DefineConstant[ h = {0.0091, Name "h"} ];

Sphere(1) = {0, 0, 0, 1};  // main lobe, thickest
Dilate {{0, 0, 0}, {0.045, 0.038, 0.042}} { Volume{1}; }
Translate {-0.015, 0, 0.008} { Volume{1}; }
Sphere(2) = {0, 0, 0, 1};  // thinner tip towards +x
Dilate {{0, 0, 0}, {0.04, 0.03, 0.026}} { Volume{2}; }
Translate {0.02, -0.006, 0.004} { Volume{2}; }
Sphere(3) = {0, 0, 0, 1};  // bulge towards +y
Dilate {{0, 0, 0}, {0.032, 0.022, 0.026}} { Volume{3}; }
Translate {-0.01, 0.018, 0.006} { Volume{3}; }
BooleanUnion(4) = { Volume{1}; Delete; }{ Volume{2, 3}; Delete; };
Box(5) = {-1, -1, -1, 2, 2, 1};  // everything below z = 0
BooleanDifference(6) = { Volume{4}; Delete; }{ Volume{5}; Delete; };
Physical Volume("tissue") = {6};

Mesh.CharacteristicLengthMin = h;
Mesh.CharacteristicLengthMax = h;
Mesh.ElementOrder = 2;
Mesh.SecondOrderLinear = 0;
Mesh.Optimize = 1;
Mesh.OptimizeThreshold = 0.7;  // optimise tets of gamma < 0.7 (default 0.3): min dihedral 11-21 deg instead of 10-14
// (Mesh.OptimizeNetgen is not compiled into Debian's gmsh 4.8.4.)
Mesh.MshFileVersion = 4.1;  // 4.1 is ~5% smaller than 2.2 here
