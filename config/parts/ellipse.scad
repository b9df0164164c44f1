// Elliptical flange: an elliptic disc with a raised elliptic rim and an offset hole.
// About 64 x 38 x 12 mm.
$fn = 72;

difference() {
  union() {
    scale([32, 19, 1]) cylinder(h = 5, r = 1);
    difference() {
      scale([26, 14, 1]) cylinder(h = 12, r = 1);
      translate([0, 0, 5]) scale([21, 10, 1]) cylinder(h = 20, r = 1);
    }
  }
  translate([0, 0, -1]) cylinder(h = 20, d = 7);
  translate([28, 0, -1]) cylinder(h = 10, d = 3.5);
  translate([-28, 0, -1]) cylinder(h = 10, d = 3.5);
}
