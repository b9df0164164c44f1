// Circuit-breaker-like part: a moulded body with a raised front, a toggle lever and
// two terminal pockets. About 54 x 36 x 27 mm.
use <MCAD/boxes.scad>
$fn = 32;

difference() {
  union() {
    translate([0, 0, 8]) roundedBox([54, 36, 16], 2, true);       // body
    translate([0, 0, 19]) roundedBox([30, 30, 8], 2, true);       // raised front
    translate([0, 0, 23]) rotate([0, 20, 0]) translate([0, 0, 3]) cube([6, 14, 10], center = true);  // toggle
  }
  for (s = [-1, 1]) translate([s * 20, 0, 12]) cube([9, 16, 10], center = true);  // terminal pockets
  for (s = [-1, 1]) translate([s * 20, 0, 0]) cylinder(d = 4, h = 40, center = true);  // screw holes
  translate([0, 0, 22.5]) cube([10, 18, 4], center = true);       // lever slot
}
