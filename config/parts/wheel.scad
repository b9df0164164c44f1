// Small cast wheel: rim, web with five lightening holes and a raised hub with a keyed bore.
// About 64 x 64 x 18 mm.
$fn = 64;

difference() {
  union() {
    difference() {
      cylinder(h = 14, d = 64);                       // rim
      translate([0, 0, 4]) cylinder(h = 20, d = 54);
    }
    cylinder(h = 18, d = 20);                         // hub
  }
  for (a = [0:72:359]) rotate([0, 0, a]) translate([17, 0, -1]) cylinder(h = 10, d = 12);
  translate([0, 0, -1]) cylinder(h = 30, d = 8);      // bore
  translate([0, 4, 9]) cube([3, 3, 30], center = true);   // key way
}
