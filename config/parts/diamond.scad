// Diamond-shaped mounting plate: a rhombus with a chamfered central boss and two holes.
// About 72 x 40 x 14 mm.
$fn = 48;

difference() {
  union() {
    linear_extrude(height = 6) polygon([[-36, 0], [0, -20], [36, 0], [0, 20]]);
    cylinder(h = 14, d1 = 22, d2 = 16);
  }
  translate([0, 0, -1]) cylinder(h = 20, d = 8);
  for (s = [-1, 1]) translate([s * 22, 0, -1]) cylinder(h = 10, d = 5);
}
