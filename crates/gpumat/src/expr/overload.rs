//! Operator overloading: `+`, `-`, unary `-` between expressions (and matrices), `*` and `/`
//! by a real. The element product is [`Ex::cwise_mul`], never `*`, to keep the element
//! product and matrix products apart.

use super::{Binary, Ex, Expr, MatRef, Scale, Unary};
use crate::matrix::Matrix;
use crate::ops::{AddOp, Neg, SubOp};
use crate::scalar::Scalar;

macro_rules! binop {
    ($tr:ident, $m:ident, $op:ident) => {
        impl<A: Expr, B: Expr<Elem = A::Elem>> std::ops::$tr<Ex<B>> for Ex<A> {
            type Output = Ex<Binary<A, B, $op>>;
            #[track_caller]
            fn $m(self, b: Ex<B>) -> Self::Output {
                Ex(Binary::new(self.0, b.0))
            }
        }
        impl<'m, A: Expr> std::ops::$tr<&'m Matrix<A::Elem>> for Ex<A> {
            type Output = Ex<Binary<A, MatRef<'m, A::Elem>, $op>>;
            #[track_caller]
            fn $m(self, b: &'m Matrix<A::Elem>) -> Self::Output {
                Ex(Binary::new(self.0, b.ex().0))
            }
        }
        impl<'m, T: Scalar, B: Expr<Elem = T>> std::ops::$tr<Ex<B>> for &'m Matrix<T> {
            type Output = Ex<Binary<MatRef<'m, T>, B, $op>>;
            #[track_caller]
            fn $m(self, b: Ex<B>) -> Self::Output {
                Ex(Binary::new(self.ex().0, b.0))
            }
        }
        impl<'m, T: Scalar> std::ops::$tr<&'m Matrix<T>> for &'m Matrix<T> {
            type Output = Ex<Binary<MatRef<'m, T>, MatRef<'m, T>, $op>>;
            #[track_caller]
            fn $m(self, b: &'m Matrix<T>) -> Self::Output {
                Ex(Binary::new(self.ex().0, b.ex().0))
            }
        }
    };
}
binop!(Add, add, AddOp);
binop!(Sub, sub, SubOp);

impl<A: Expr> std::ops::Neg for Ex<A> {
    type Output = Ex<Unary<A, Neg>>;
    fn neg(self) -> Self::Output {
        Ex(Unary::new(self.0))
    }
}
impl<'m, T: Scalar> std::ops::Neg for &'m Matrix<T> {
    type Output = Ex<Unary<MatRef<'m, T>, Neg>>;
    fn neg(self) -> Self::Output {
        Ex(Unary::new(self.ex().0))
    }
}

macro_rules! scale_ops {
    ($r:ty) => {
        impl<A: Expr> std::ops::Mul<$r> for Ex<A>
        where
            A::Elem: Scalar<Real = $r>,
        {
            type Output = Ex<Scale<A>>;
            fn mul(self, s: $r) -> Self::Output {
                Ex(Scale::new(self.0, s))
            }
        }
        impl<A: Expr> std::ops::Mul<Ex<A>> for $r
        where
            A::Elem: Scalar<Real = $r>,
        {
            type Output = Ex<Scale<A>>;
            fn mul(self, e: Ex<A>) -> Self::Output {
                Ex(Scale::new(e.0, self))
            }
        }
        impl<A: Expr> std::ops::Div<$r> for Ex<A>
        where
            A::Elem: Scalar<Real = $r>,
        {
            type Output = Ex<Scale<A>>;
            fn div(self, s: $r) -> Self::Output {
                Ex(Scale::new(self.0, 1.0 / s))
            }
        }
        impl<'m, T: Scalar<Real = $r>> std::ops::Mul<$r> for &'m Matrix<T> {
            type Output = Ex<Scale<MatRef<'m, T>>>;
            fn mul(self, s: $r) -> Self::Output {
                Ex(Scale::new(self.ex().0, s))
            }
        }
        impl<'m, T: Scalar<Real = $r>> std::ops::Mul<&'m Matrix<T>> for $r {
            type Output = Ex<Scale<MatRef<'m, T>>>;
            fn mul(self, m: &'m Matrix<T>) -> Self::Output {
                Ex(Scale::new(m.ex().0, self))
            }
        }
    };
}
scale_ops!(f32);
scale_ops!(f64);
